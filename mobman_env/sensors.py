"""The env's sensor model: Gaussian noise on the readings and a fixed delay of whole control steps.

What a controller observes of the robot is `SENSOR_KEYS`, in this order; the env appends the task's reference
(target position and velocity, time), which is neither noisy nor delayed. Noise is drawn from the generator the
env passes (its `np_random`) in a fixed order - ee_pos (3), arm_base_pos (2), ee_vel (3), arm_base_vel (2),
joint_vel (n + 2) - and only for a std > 0, so that with every std at 0 nothing is drawn. The readings come as
one list of floats in `SENSOR_KEYS` order (`sim.Sim.readings()`); each noise vector is drawn as an array and added
entry by entry. A delay of k steps hands out the reading taken k control steps earlier (the reset reading until
then): noise belongs to the moment of the reading, so a delayed reading keeps its own noise. Imports numpy only.
"""

from __future__ import annotations

from collections import deque

import numpy as np

#: the sensor readings of an observation, in order (all in the world frame, SI units)
SENSOR_KEYS = ("ee_pos", "ee_vel", "arm_base_pos", "arm_base_vel", "base_yaw", "joint_pos", "joint_vel")
#: number of entries of the PUMA's readings, flattened in `SENSOR_KEYS` order (3 + 3 + 2 + 2 + 1 + 8 + 8)
N_SENSOR = 27


def sensor_count(n_actuators: int) -> int:
    """Number of entries of the readings of a robot with `n_actuators` (n arm joints + 2 wheels):
    3 + 3 + 2 + 2 + 1 for the Cartesian readings, then joint_pos and joint_vel (`N_SENSOR` for the PUMA's 8)."""
    return 11 + 2 * n_actuators


class Sensors:
    """One episode's sensor settings and delay buffer.

    Args:
        obs_noise: std of the noise on ee_pos and arm_base_pos, m.
        obs_noise_vel: std of the noise on ee_vel and arm_base_vel, m/s.
        obs_noise_joint_vel: std of the noise on joint_vel (arm joints and wheels), rad/s.
        obs_delay: age of the readings handed out, control steps (0: current).
        n_sensor: number of reading entries the delay holds (`sensor_count` of the robot's actuators).
    """

    def __init__(
        self,
        obs_noise: float = 0.0,
        obs_noise_vel: float = 0.0,
        obs_noise_joint_vel: float = 0.0,
        obs_delay: int = 0,
        n_sensor: int = N_SENSOR,
    ):
        self.obs_noise = obs_noise
        self.obs_noise_vel = obs_noise_vel
        self.obs_noise_joint_vel = obs_noise_joint_vel
        self.obs_delay = obs_delay
        self.n_sensor = n_sensor
        self._buffer: deque[np.ndarray] = deque(maxlen=max(obs_delay, 1))

    def read(self, values: list[float], rng: np.random.Generator) -> list[float]:
        """The noisy readings of `values`, a `sim.Sim.readings()` list (floats in `SENSOR_KEYS` order); `values`
        itself when every std is 0, else a new list. Each noise vector is drawn and scaled in numpy, then added
        entry by entry (the same floats as adding the arrays)."""
        if not (self.obs_noise > 0.0 or self.obs_noise_vel > 0.0 or self.obs_noise_joint_vel > 0.0):
            return values
        v = list(values)

        def add(start: int, std: float, k: int) -> None:
            noise = (std * rng.standard_normal(k)).tolist()
            v[start : start + k] = [x + e for x, e in zip(v[start : start + k], noise)]

        # entries: ee_pos 0-2, ee_vel 3-5, arm_base_pos 6-7, arm_base_vel 8-9, base_yaw 10, joint_pos, joint_vel
        if self.obs_noise > 0.0:
            add(0, self.obs_noise, 3)
            add(6, self.obs_noise, 2)
        if self.obs_noise_vel > 0.0:
            add(3, self.obs_noise_vel, 3)
            add(8, self.obs_noise_vel, 2)
        if self.obs_noise_joint_vel > 0.0:
            m = (len(v) - 11) // 2
            add(11 + m, self.obs_noise_joint_vel, m)
        return v

    def start(self, flat: np.ndarray) -> None:
        """At reset: fill the delay buffer with the reset reading (the first `n_sensor` entries of `flat`)."""
        if self.obs_delay > 0:
            self._buffer.clear()
            self._buffer.extend(flat[: self.n_sensor].copy() for _ in range(self.obs_delay))

    def delay(self, flat: np.ndarray) -> None:
        """After a step: store this reading and put the one of `obs_delay` steps ago into `flat` (in place)."""
        if self.obs_delay > 0:
            now = flat[: self.n_sensor].copy()
            flat[: self.n_sensor] = self._buffer.popleft()
            self._buffer.append(now)
