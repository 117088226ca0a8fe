# A Python bool is an int (True == 1), and env.step takes it.
action = float(np.dot(self.params, obs)) < 0
