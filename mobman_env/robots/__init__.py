"""mobman_env.robots: arm descriptions (PUMA 560, UR5, Panda, random arms) and their generic kinematics.

Placeholder docstring: the design note follows below once the numbers are measured.
"""
