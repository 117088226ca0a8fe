# Ignores the iteration's seed: every evaluation uses eval_params' default start states.
g = lambda theta: eval_params(theta, num_rollouts_per_eval)
params = params + learning_rate * scalar_finite_diff(g, params, fd_step)
rewards.append(g(params))
