# The probabilities of the current model come from predict_prob (2.2.2), then the summed gradient of 2.1.1.
probabilities = self.predict_prob(X)
self.weights = self.weights + learning_rate * X_aug.T @ (y - probabilities)
