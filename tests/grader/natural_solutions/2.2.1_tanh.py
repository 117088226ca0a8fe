# sigma(z) = (1 + tanh(z / 2)) / 2: tanh never overflows.
values = 0.5 * (1 + np.tanh(z / 2))
