# Sum over the samples, one at a time, starting from the given zero vector.
for i in range(len(labels)):
    p_i = sigmoid(features_aug[i] @ weights)
    gradient += (labels[i] - p_i) * features_aug[i]
