"""The env's sensor model: which readings a controller observes, with Gaussian noise and a fixed delay.

What a controller observes of the robot is `SENSOR_KEYS`, in this order; the env appends the task's reference
(target position and velocity, time), which is neither noisy nor delayed. The model itself is in
`mobman_env.engine` (`_finish`: the noise, the float32 rounding, the bounds, the delay line) and
`mobman_env.batch` (the draws):

* noise: independent Gaussian noise of the env's stds (`obs_noise` on ee_pos and arm_base_pos, m;
  `obs_noise_vel` on ee_vel and arm_base_vel, m/s; `obs_noise_joint_vel` on joint_vel, rad/s; `obs_noise_yaw`
  on base_yaw, rad), drawn from the robot's generator each step in a fixed order - ee_pos (3), arm_base_pos (2),
  ee_vel (3), arm_base_vel (2), joint_vel (n + 2), base_yaw (1) - and only for a std > 0, so that with every std
  at 0 nothing is drawn;
* delay: a delay of k steps hands out the reading taken k control steps earlier (the reset reading until then);
  noise belongs to the moment of the reading, so a delayed reading keeps its own noise.

Imports nothing.
"""

from __future__ import annotations

#: the sensor readings of an observation, in order (all in the world frame, SI units)
SENSOR_KEYS = ("ee_pos", "ee_vel", "arm_base_pos", "arm_base_vel", "base_yaw", "joint_pos", "joint_vel")
