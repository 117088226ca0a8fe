# One step for classifier c written out with the gradient of 2.1.1 on its one-vs-rest labels.
labels_c = np.where(y == c, 1, 0)
classifier = self.classifiers[c]
classifier.weights = classifier.weights + learning_rate * log_likelihood_gradient(classifier.weights, X, labels_c)
