# One environment reused (gymnasium's idiom): the first episode seeded, the others continue it.
from hwlib.cartpole import make_env
env = make_env()
rewards = [run_policy(policy, seed=seed, env=env)]
for k in range(1, num_rollouts):
    rewards.append(run_policy(policy, env=env))
mean_reward = sum(rewards) / num_rollouts
