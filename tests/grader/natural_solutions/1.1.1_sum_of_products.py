score = 0.0
for weight, value in zip(self.params, obs):
    score += weight * value
action = 1 if score < 0 else 0
