def reward_of(theta):
    return eval_params(theta, num_rollouts=num_rollouts_per_eval, seed=eval_seed)

step_sizes = np.full(4, fd_step)
grad = scalar_finite_diff(reward_of, params, step_sizes)
params += learning_rate * grad
rewards.append(reward_of(params))
