labels_c = (y == c).astype(int)
self.classifiers[c].gradient_ascent_step(X, labels_c, learning_rate)
