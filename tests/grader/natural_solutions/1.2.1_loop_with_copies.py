for i in range(len(x)):
    x_plus = x.copy()
    x_minus = x.copy()
    x_plus[i] = x_plus[i] + h[i]
    x_minus[i] = x_minus[i] - h[i]
    gradient[i] = (f(x_plus) - f(x_minus)) / (2 * h[i])
