# "Use the expression you derived": the 2.1.1 code already computes it.
self.weights = self.weights + learning_rate * log_likelihood_gradient(self.weights, X, y)
