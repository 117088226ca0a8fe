tried = {
    "always left": (0.0, 0.0, 0.0, 0.0),
    "always right": (0.0, -1.0, 0.0, 1.0),
    "pole angle only": (0.0, 0.0, -1.0, 0.0),
    "angle and angular velocity": (0.0, 0.0, -1.0, -1.0),
}
