# The derived gradient for all samples at once: each sample's feature vector times its error.
errors = labels - sigmoid(features_aug @ weights)
gradient = features_aug.T @ errors
