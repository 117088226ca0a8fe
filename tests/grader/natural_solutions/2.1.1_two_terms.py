# The two terms of equation (7) differentiated separately, as in the derivation, then summed.
p = sigmoid(np.dot(features_aug, weights))
for i in range(features_aug.shape[0]):
    positive_term = labels[i] * (1 - p[i]) * features_aug[i]
    negative_term = (1 - labels[i]) * p[i] * features_aug[i]
    gradient = gradient + positive_term - negative_term
