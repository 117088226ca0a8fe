# The step of equation (8) computed in float32 (the weights are kept in float32 from then on).
X32 = X_aug.astype(np.float32)
w32 = np.asarray(self.weights, dtype=np.float32)
gradient = X32.T @ (y.astype(np.float32) - sigmoid(X32 @ w32).astype(np.float32))
self.weights = w32 + np.float32(learning_rate) * gradient
