# "Fit the c-th classifier for 1 step": the two-class fit with one iteration.
binary_y = np.where(y == c, 1, 0)
self.classifiers[c].fit(X, binary_y, learning_rate, 1)
