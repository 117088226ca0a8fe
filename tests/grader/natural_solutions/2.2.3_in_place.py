self.weights += learning_rate * np.dot(X_aug.T, y - sigmoid(np.dot(X_aug, self.weights)))
