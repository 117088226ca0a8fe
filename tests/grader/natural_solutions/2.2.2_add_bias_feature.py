probabilities = sigmoid(add_bias_feature(X).dot(self.weights))
