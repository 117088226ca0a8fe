# A list of the partial derivatives, returned as an array of its own (shape (N,); (1,) for a single number x).
grads = []
for i in range(len(x)):
    e = np.zeros(len(x))
    e[i] = 1.0
    grads.append((f(x + h[i] * e) - f(x - h[i] * e)) / (2 * h[i]))
return np.array(grads)
