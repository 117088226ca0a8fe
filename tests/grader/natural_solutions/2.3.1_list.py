new_labels = np.array([1 if label == c else 0 for label in y])
classifier = self.classifiers[c]
classifier.gradient_ascent_step(X, new_labels, learning_rate)
