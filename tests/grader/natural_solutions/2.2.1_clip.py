# Clip the input so that exp cannot overflow.
z = np.clip(z, -500, 500)
values = 1.0 / (1.0 + np.exp(-z))
