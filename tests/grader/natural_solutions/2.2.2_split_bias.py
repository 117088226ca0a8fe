# w^T x + b without building the augmented matrix: the bias is the last weight.
w, b = self.weights[:-1], self.weights[-1]
probabilities = sigmoid(X @ w + b)
