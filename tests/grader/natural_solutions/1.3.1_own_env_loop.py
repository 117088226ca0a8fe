# Its own gymnasium loop: one environment, reset(seed=seed + k) for each episode, step until done.
import gymnasium as gym
env = gym.make("CartPole-v1")
total = 0.0
for k in range(num_rollouts):
    obs, info = env.reset(seed=seed + k)
    done = False
    while not done:
        obs, reward, terminated, truncated, info = env.step(policy(obs))
        total += reward
        done = terminated or truncated
env.close()
mean_reward = total / num_rollouts
