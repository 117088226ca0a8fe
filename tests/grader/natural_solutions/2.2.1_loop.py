# Entry by entry.
flat = z.reshape(-1)
out = np.zeros(flat.shape)
for i in range(flat.size):
    out[i] = 1.0 / (1.0 + np.exp(-flat[i]))
values = out.reshape(z.shape)
