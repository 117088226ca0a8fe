grad = scalar_finite_diff(lambda p: eval_params(p, num_rollouts_per_eval, eval_seed), params, fd_step)
params = params + learning_rate * grad
rewards.append(eval_params(params, num_rollouts_per_eval, eval_seed))
