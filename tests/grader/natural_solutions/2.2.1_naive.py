values = 1 / (1 + np.exp(-z))
