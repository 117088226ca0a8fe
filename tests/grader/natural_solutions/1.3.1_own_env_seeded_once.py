# The environment seeded once by a reset of its own, then reset() before every episode.
import gymnasium as gym
env = gym.make("CartPole-v1")
env.reset(seed=seed)
rewards = []
for k in range(num_rollouts):
    obs, _ = env.reset()
    total, done = 0.0, False
    while not done:
        obs, reward, terminated, truncated, _ = env.step(policy(obs))
        total += reward
        done = terminated or truncated
    rewards.append(total)
mean_reward = np.mean(rewards)
