if np.dot(self.params, obs) < 0:
    action = 1
else:
    action = 0
