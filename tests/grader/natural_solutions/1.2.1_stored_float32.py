# Equation (3) stored in a float32 array of its own: every partial derivative rounded to float32.
grad = np.zeros(len(x), dtype=np.float32)
for i in range(len(x)):
    e = np.zeros(len(x))
    e[i] = h[i]
    grad[i] = (f(x + e) - f(x - e)) / (2 * h[i])
return grad
