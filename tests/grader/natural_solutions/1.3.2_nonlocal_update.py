def update():
    nonlocal params
    g = lambda p: eval_params(p, num_rollouts_per_eval, seed=eval_seed)
    params = params + learning_rate * scalar_finite_diff(g, params, fd_step)
    return g(params)

rewards.append(update())
