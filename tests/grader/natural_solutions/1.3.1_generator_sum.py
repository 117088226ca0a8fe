mean_reward = sum(run_policy(policy, seed=seed + i) for i in range(num_rollouts)) / num_rollouts
