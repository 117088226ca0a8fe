X_train, X_test, y_train, y_test = train_test_split(data.features, data.labels, settings.TEST_FRACTION, settings.SPLIT_SEED)

model = MultiClassLogisticRegressionClassifier(220, 7)
train_accuracies = model.fit(X_train, y_train, settings.P2_LEARNING_RATE, settings.P2_NUM_ITERATIONS)

test_predictions = model.predict(X_test)
test_accuracy = accuracy(y_test, test_predictions)
first_above_99 = first_iteration_above(train_accuracies, settings.TARGET_ACCURACY)
print("train accuracy:", train_accuracies[-1], "test accuracy:", test_accuracy)
