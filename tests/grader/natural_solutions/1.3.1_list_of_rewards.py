rewards = []
for k in range(num_rollouts):
    rewards.append(run_policy(policy, seed=seed + k))
mean_reward = np.mean(rewards)
