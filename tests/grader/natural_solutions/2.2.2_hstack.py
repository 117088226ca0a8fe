ones = np.ones((X.shape[0], 1))
X_aug = np.hstack((X, ones))
probabilities = sigmoid(X_aug @ self.weights)
