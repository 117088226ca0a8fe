gradient = X_aug.T @ (y - sigmoid(X_aug @ self.weights))
self.weights = self.weights + learning_rate * gradient
