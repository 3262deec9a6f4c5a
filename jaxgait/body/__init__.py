"""Layer 1: the multibody (planar kinematics read from the MJCF) and joint conventions."""
