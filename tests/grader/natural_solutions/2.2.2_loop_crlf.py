probabilities = np.zeros(len(X))
for i in range(len(X)):
    x_tilde = np.append(X[i], 1.0)
    probabilities[i] = sigmoid(np.dot(self.weights, x_tilde))
