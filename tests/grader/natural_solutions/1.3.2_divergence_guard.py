def g(p):
    return eval_params(p, num_rollouts_per_eval, seed=eval_seed)

gradient = scalar_finite_diff(g, params, fd_step)
if not np.all(np.isfinite(gradient)):
    print("the gradient is not finite: training stops here")
    break
params = params + learning_rate * gradient
rewards.append(g(params))
