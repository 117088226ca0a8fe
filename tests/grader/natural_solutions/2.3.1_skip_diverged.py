classifier = self.classifiers[c]
if not np.all(np.isfinite(classifier.weights)):
    continue  # a classifier that has diverged is left as it is
labels_c = np.where(y == c, 1, 0)
classifier.gradient_ascent_step(X, labels_c, learning_rate)
