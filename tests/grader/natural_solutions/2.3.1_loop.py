two_class_labels = np.zeros(len(y))
for i in range(len(y)):
    if y[i] == c:
        two_class_labels[i] = 1
self.classifiers[c].gradient_ascent_step(X, two_class_labels, learning_rate)
