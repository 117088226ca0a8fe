# The partial derivatives as a plain list, one per coordinate.
result = []
for i in range(len(x)):
    up = x.copy()
    down = x.copy()
    up[i] += h[i]
    down[i] -= h[i]
    result.append((f(up) - f(down)) / (2 * h[i]))
return result
