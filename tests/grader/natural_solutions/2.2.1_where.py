# The two algebraically equal forms, each used on its own side of 0 (numpy still evaluates both
# everywhere, so it may warn about overflow; the values it keeps are right).
values = np.where(z >= 0, 1 / (1 + np.exp(-z)), np.exp(z) / (1 + np.exp(z)))
