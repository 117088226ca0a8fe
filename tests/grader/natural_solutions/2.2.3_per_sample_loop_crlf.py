# The gradient of 2.1.1 summed sample by sample, then one step of equation (8).
gradient = np.zeros(len(self.weights))
for i in range(len(y)):
    p_i = sigmoid(X_aug[i] @ self.weights)
    gradient += (y[i] - p_i) * X_aug[i]
self.weights = self.weights + learning_rate * gradient
