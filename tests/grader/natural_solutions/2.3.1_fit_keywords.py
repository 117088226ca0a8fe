# The two-class fit for exactly 1 step, on the labels of class c.
labels = np.array([1 if label == c else 0 for label in y])
self.classifiers[c].fit(X, labels, learning_rate=learning_rate, n_iters=1)
