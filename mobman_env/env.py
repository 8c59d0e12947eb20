"""`WheeledPumaEnv`: end-effector path tracking with a PUMA 560 on a two-wheel differential-drive platform."""

from __future__ import annotations

import math
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from mobman_env.params import RobotParams
from mobman_env.paths import path_from_spec, validate_spec
from mobman_env.sim import DYNAMICS_MODES, Sim

#: theta(0) of the paper's section IV, rad.
PAPER_ARM_JOINT_POS = (0.0, math.pi / 4, 0.0, 2 * math.pi / 3, -math.pi / 4, 0.0)
#: Platform pose (x, y, yaw) of P_0 at the start: heading pi faces the paper's circle, which lies towards -x.
PAPER_BASE_POSE = (0.0, 0.0, math.pi)
#: The paper's circle (section IV): radius 0.4 m, tilted pi/6, 20 s, centre towards -x from the start.
PAPER_CIRCLE = {"type": "circle", "radius": 0.4, "tilt": math.pi / 6, "yaw": math.pi, "duration": 20.0}
DEFAULT_REWARD_WEIGHTS = {"tracking": 1.0, "effort": 1e-3}
TIP_ANGLE = math.radians(30.0)  # rad, roll or pitch beyond which the platform counts as tipped over

OBS_KEYS = (
    "ee_pos",
    "ee_vel",
    "arm_base_pos",
    "arm_base_vel",
    "base_yaw",
    "joint_pos",
    "joint_vel",
    "target_pos",
    "target_vel",
    "time",
)


def _check_nonneg(value: Any, name: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number >= 0, got {value!r}") from None
    if not (v >= 0.0 and math.isfinite(v)):
        raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")
    return v


def _vector(value: Any, n: int, name: str, example: str) -> np.ndarray:
    arr = np.asarray(value, dtype=float) if value is not None else None
    if arr is None or arr.shape != (n,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be {n} finite numbers (e.g. {example}), got {value!r}")
    return arr


class WheeledPumaEnv(gym.Env):
    r"""Track a time-parameterised path with the end-effector of a wheeled PUMA 560.

    ## Description
    A PUMA 560 arm (standard DH table of Corke & Armstrong-Helouvry, 0.2 m tool) stands on a two-wheel
    differential-drive platform, its base P_c `mount_offset` = 0.1 m ahead of the axle centre P_0, its shoulder
    0.6 m above the ground. The agent commands the speeds of the 6 arm joints and the 2 wheels; the task is to
    keep the end-effector point r_a on a desired path r_d(t) that is fixed in the world and starts where the
    end-effector starts (the initial error is 0). This is the task of "Neural-Network-Based Control of Wheeled
    Mobile Manipulators with Unknown Kinematic Models" (section IV). Each reset draws a "worn" true robot whose
    link lengths, tool, wheel radius, half track and mount offset differ from the catalogue by `model_error`
    (relative std), so model-based controllers that use `nominal_params` make errors, as in the paper.

    ## Action Space
    `Box(-1, 1, (8,), float32)`, scaled by `action_scale` (rad/s) to joint and wheel speeds:

    | index | actuator | scale (rad/s) |
    |---|---|---|
    | 0-2 | arm joints 1-3 | 3.0 |
    | 3-5 | arm joints 4-6 (joint 6 turns about the tool axis: it never moves the point) | 5.0 |
    | 6 | left wheel (+y side) | 10.0 (2 m/s rim speed) |
    | 7 | right wheel (-y side) | 10.0 |

    Values outside [-1, 1] are clipped (`info["action_clipped"]`, `info["n_clipped"]`); NaN, inf or a wrong
    shape raise `ValueError`.

    ## Observation Space
    A `Dict` of float32 `Box`es, world frame, SI units (values are clipped into the bounds):

    | key | shape | meaning | unit |
    |---|---|---|---|
    | ee_pos | (3,) | end-effector position r_a (+ `obs_noise`) | m |
    | ee_vel | (3,) | end-effector velocity (+ `obs_noise_vel`) | m/s |
    | arm_base_pos | (2,) | p_c, x-y of the arm mount (+ `obs_noise`) | m |
    | arm_base_vel | (2,) | p_c velocity (+ `obs_noise_vel`) | m/s |
    | base_yaw | (1,) | platform heading phi, continuous (not wrapped) | rad |
    | joint_pos | (8,) | 6 arm joint angles, left and right wheel angles | rad |
    | joint_vel | (8,) | their speeds | rad/s |
    | target_pos | (3,) | desired position r_d(t) | m |
    | target_vel | (3,) | desired velocity r_d_dot(t) | m/s |
    | time | (1,) | time since reset t | s |

    ## Rewards
    Named terms, reported in `info["reward_terms"]` and summed exactly:
    `tracking = -w_tracking * ||r_d - r_a||` (m, noise-free) and `effort = -w_effort * ||a||^2` (a: the
    normalised action after clipping). Weights from `reward_weights` (default tracking 1.0, effort 1e-3).

    ## Starting State
    Arm at `arm_joint_pos` (default the paper's theta(0) = [0, pi/4, 0, 2pi/3, -pi/4, 0] rad), wheels at 0 rad,
    platform at `base_pose` (x, y of P_0 in m, yaw in rad; default [0, 0, pi]), at rest. The path starts at the
    end-effector. Reset options `"path"` (spec dict), `"arm_joint_pos"` (6 or 8 numbers) and `"base_pose"` (3
    numbers) override the constructor for one episode. `info["task"]` echoes the path spec, its start, the joint
    vector and the base pose; `info["true_params_hash"]` identifies the true robot.

    ## Episode End
    Truncated when t reaches the path's duration (no `max_episode_steps`: 2000 steps for 20 s at 100 Hz).
    Terminated if the platform tips over (roll or pitch > 30 deg) or, when `error_bound` (m) is set, the
    tracking error exceeds it.

    ## Arguments
    | argument | default | meaning |
    |---|---|---|
    | path | None | path spec dict (see `mobman_env.paths`); None: the paper's circle |
    | arm_joint_pos | None | 6 arm angles (or 8 with wheels), rad; None: the paper's theta(0) |
    | base_pose | None | (x, y, yaw) of P_0, m and rad; None: (0, 0, pi) |
    | dynamics | "physics" | "physics" (PyBullet contact dynamics) or "kinematic" (the paper's ideal model) |
    | control_freq | 100.0 | control steps per second, Hz |
    | n_substeps | 2 | PyBullet steps per control step (physics mode) |
    | model_error | 0.05 | relative std of the true robot's kinematic lengths vs the nominal ones |
    | obs_noise | 0.0 | std of the Gaussian noise on ee_pos and arm_base_pos, m |
    | obs_noise_vel | 0.0 | std of the Gaussian noise on ee_vel and arm_base_vel, m/s |
    | reward_weights | None | dict with keys "tracking", "effort"; None: {"tracking": 1.0, "effort": 1e-3} |
    | error_bound | None | terminate when the tracking error exceeds this, m; None: never |
    | render_mode | None | None, "rgb_array" (headless TinyRenderer) or "human" (needs a display) |

    ## Version History
    * v0: initial release.
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["human", "rgb_array"], "render_fps": 25}

    def __init__(
        self,
        path: dict | None = None,
        arm_joint_pos: Any = None,
        base_pose: Any = None,
        dynamics: str = "physics",
        control_freq: float = 100.0,
        n_substeps: int = 2,
        model_error: float = 0.05,
        obs_noise: float = 0.0,
        obs_noise_vel: float = 0.0,
        reward_weights: dict | None = None,
        error_bound: float | None = None,
        render_mode: str | None = None,
    ):
        if dynamics not in DYNAMICS_MODES:
            raise ValueError(f"unknown dynamics mode {dynamics!r}; accepted: {', '.join(DYNAMICS_MODES)}")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"unknown render_mode {render_mode!r}; accepted: None, 'rgb_array', 'human'")
        try:
            control_freq = float(control_freq)
        except (TypeError, ValueError):
            raise ValueError(f"control_freq must be a number > 0 (Hz), got {control_freq!r}") from None
        if not (control_freq > 0 and math.isfinite(control_freq)):
            raise ValueError(f"control_freq must be a finite number > 0 (Hz), got {control_freq!r}")
        if isinstance(n_substeps, bool) or not isinstance(n_substeps, (int, np.integer)) or n_substeps < 1:
            raise ValueError(f"n_substeps must be an integer >= 1, got {n_substeps!r}")
        self.model_error = _check_nonneg(model_error, "model_error")
        self.obs_noise = _check_nonneg(obs_noise, "obs_noise")
        self.obs_noise_vel = _check_nonneg(obs_noise_vel, "obs_noise_vel")
        if error_bound is not None:
            error_bound = _check_nonneg(error_bound, "error_bound")
        weights = dict(DEFAULT_REWARD_WEIGHTS)
        if reward_weights is not None:
            if not isinstance(reward_weights, dict) or set(reward_weights) - set(DEFAULT_REWARD_WEIGHTS):
                raise ValueError(
                    f"reward_weights must be a dict with keys from {sorted(DEFAULT_REWARD_WEIGHTS)}, got {reward_weights!r}"
                )
            weights.update({k: _check_nonneg(v, f"reward_weights[{k!r}]") for k, v in reward_weights.items()})
        self.reward_weights = weights
        self.error_bound = error_bound
        self.path_spec = validate_spec(PAPER_CIRCLE if path is None else path)
        self.arm_joint_pos = self._joint_vector(PAPER_ARM_JOINT_POS if arm_joint_pos is None else arm_joint_pos)
        self.base_pose = _vector(PAPER_BASE_POSE if base_pose is None else base_pose, 3, "base_pose", "[0, 0, 3.1416]")
        self.dynamics = dynamics
        self.control_freq = control_freq
        self.dt = 1.0 / control_freq
        self.n_substeps = int(n_substeps)
        self.render_mode = render_mode

        self.nominal_params = RobotParams.nominal()
        self.true_params = self.nominal_params
        self.action_scale = self.nominal_params.action_scale
        self.action_space = spaces.Box(-1.0, 1.0, (8,), np.float32)
        self.observation_space = self._make_observation_space()
        # one flat float32 vector per step, clipped once and handed out as views, in OBS_KEYS order
        sizes = [self.observation_space[k].shape[0] for k in OBS_KEYS]
        ends = np.cumsum(sizes)
        self._obs_slices = [(k, slice(e - n, e)) for k, n, e in zip(OBS_KEYS, sizes, ends)]
        self._obs_low = np.concatenate([self.observation_space[k].low for k in OBS_KEYS])
        self._obs_high = np.concatenate([self.observation_space[k].high for k in OBS_KEYS])

        self._sim = Sim(dynamics, self.dt, self.n_substeps, gui=(render_mode == "human"))
        self._path = None
        self._step_count = 0
        self._n_steps = 0
        self._n_clipped = 0
        self._limit_hits = 0
        self._task: dict = {}

    # --- construction helpers --------------------------------------------------------------------------
    def _joint_vector(self, value: Any) -> np.ndarray:
        arr = np.asarray(value, dtype=float) if value is not None else None
        if arr is None or arr.shape not in ((6,), (8,)) or not np.all(np.isfinite(arr)):
            raise ValueError(
                f"arm_joint_pos must be 6 arm angles or 8 (arm + left, right wheel) finite numbers in rad, "
                f"e.g. {list(np.round(PAPER_ARM_JOINT_POS, 4))}, got {value!r}"
            )
        if arr.shape == (6,):
            arr = np.concatenate([arr, [0.0, 0.0]])
        p = RobotParams.nominal()
        lo, hi = np.array(p.joint_lower), np.array(p.joint_upper)
        if np.any(arr[:6] < lo) or np.any(arr[:6] > hi):
            raise ValueError(
                f"arm_joint_pos {list(arr[:6])} is outside the joint limits: lower {list(np.round(lo, 4))}, "
                f"upper {list(np.round(hi, 4))} (rad)"
            )
        return arr

    @staticmethod
    def _make_observation_space() -> spaces.Dict:
        f32 = np.float32
        big_pos, big_vel = 1000.0, 100.0  # m and m/s: wide enough for any physics overshoot or drive-away

        def box(n, lim):
            return spaces.Box(-lim, lim, (n,), f32)

        return spaces.Dict(
            {
                "ee_pos": box(3, big_pos),
                "ee_vel": box(3, big_vel),
                "arm_base_pos": box(2, big_pos),
                "arm_base_vel": box(2, big_vel),
                "base_yaw": box(1, 1e5),
                "joint_pos": box(8, 1e5),
                "joint_vel": box(8, 1e3),
                "target_pos": box(3, big_pos),
                "target_vel": box(3, big_vel),
                "time": spaces.Box(0.0, 1e5, (1,), f32),
            }
        )

    # --- gym API ---------------------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        options = dict(options or {})
        unknown = sorted(set(options) - {"path", "arm_joint_pos", "base_pose"})
        if unknown:
            raise ValueError(f"unknown reset option(s) {unknown}; accepted: 'path', 'arm_joint_pos', 'base_pose'")
        spec = validate_spec(options["path"]) if "path" in options else self.path_spec
        q0 = self._joint_vector(options["arm_joint_pos"]) if "arm_joint_pos" in options else self.arm_joint_pos
        pose = (
            _vector(options["base_pose"], 3, "base_pose", "[0, 0, 3.1416]")
            if "base_pose" in options
            else self.base_pose
        )
        # one RNG stream, in a fixed order: true robot, then the path's own seed, then sensor noise
        self.true_params = self.nominal_params.perturbed(self.np_random, self.model_error)
        self._sim.reset(self.true_params, q0, pose)
        state = self._sim.state()
        self._path = path_from_spec(spec, state.ee_pos, self.np_random)
        self._n_steps = max(1, int(round(self._path.duration * self.control_freq)))
        self._step_count = 0
        self._n_clipped = 0
        self._limit_hits = 0
        self._task = {
            "path": self._path.to_spec(),
            "start": [float(v) for v in state.ee_pos],
            "arm_joint_pos": [float(v) for v in q0],
            "base_pose": [float(v) for v in pose],
            "duration": float(self._path.duration),
            "n_steps": self._n_steps,
        }
        self._params_hash = self.true_params.hash()
        if self.render_mode is not None:
            ts = np.linspace(0.0, self._path.duration, 60)
            self._path_points = np.array([self._path.position(t) for t in ts])
            self._sim.draw_path(self._path_points)
        obs = self._observation(state, 0.0, *self._path.position_velocity(0.0))
        info = {
            "task": self._task,
            "true_params_hash": self._params_hash,
            "ee_pos_true": state.ee_pos.copy(),
            "tracking_error": 0.0,
            "n_clipped": 0,
            "joint_limit_hits": 0,
        }
        return obs, info

    def step(self, action):
        if self._path is None:
            raise RuntimeError("call reset() before step()")
        a = np.asarray(action, dtype=np.float64)
        if a.shape != (8,):
            raise ValueError(
                f"action must have shape (8,) (6 arm joints, left wheel, right wheel), got shape {a.shape}"
            )
        if not np.all(np.isfinite(a)):
            raise ValueError(
                f"action must be finite, got {a.tolist()} (NaN or inf at {np.flatnonzero(~np.isfinite(a)).tolist()})"
            )
        clipped = bool(np.any(np.abs(a) > 1.0))
        if clipped:
            a = np.clip(a, -1.0, 1.0)
            self._n_clipped += 1
        self._limit_hits += self._sim.step(a * self.action_scale)
        self._step_count += 1
        t = self._step_count * self.dt
        state = self._sim.state()
        r_d, v_d = self._path.position_velocity(t)
        err = float(np.linalg.norm(r_d - state.ee_pos))
        terms = {
            "tracking": -self.reward_weights["tracking"] * err,
            "effort": -self.reward_weights["effort"] * float(a @ a),
        }
        reward = float(sum(terms.values()))
        tipped = max(abs(state.roll_pitch[0]), abs(state.roll_pitch[1])) > TIP_ANGLE
        terminated = tipped or (self.error_bound is not None and err > self.error_bound)
        truncated = self._step_count >= self._n_steps
        obs = self._observation(state, t, r_d, v_d)
        info = {
            "ee_pos_true": state.ee_pos.copy(),
            "tracking_error": err,
            "reward_terms": terms,
            "action_clipped": clipped,
            "n_clipped": self._n_clipped,
            "joint_limit_hits": self._limit_hits,
            "tipped_over": tipped,
            "true_params_hash": self._params_hash,
        }
        return obs, reward, terminated, truncated, info

    def _observation(self, state, t: float, r_d: np.ndarray, v_d: np.ndarray) -> dict:
        ee_pos, pc = state.ee_pos, state.arm_base_pos
        ee_vel, pc_vel = state.ee_vel, state.arm_base_vel
        if self.obs_noise > 0.0:
            ee_pos = ee_pos + self.obs_noise * self.np_random.standard_normal(3)
            pc = pc + self.obs_noise * self.np_random.standard_normal(2)
        if self.obs_noise_vel > 0.0:
            ee_vel = ee_vel + self.obs_noise_vel * self.np_random.standard_normal(3)
            pc_vel = pc_vel + self.obs_noise_vel * self.np_random.standard_normal(2)
        flat = np.concatenate(
            [ee_pos, ee_vel, pc, pc_vel, state.base_pose[2:], state.joint_pos, state.joint_vel, r_d, v_d, (t,)]
        ).astype(np.float32)
        np.clip(flat, self._obs_low, self._obs_high, out=flat)
        return {k: flat[sl] for k, sl in self._obs_slices}

    def render(self):
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; make the env with render_mode='rgb_array'")
            return None
        if self._path is None:
            raise RuntimeError("call reset() before render()")
        # look at the middle of the box holding the path and the platform
        base = self._sim.state().base_pose
        pts = np.vstack([self._path_points, [base[0], base[1], 0.3], [base[0], base[1], 1.0]])
        target = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
        distance = 1.2 + 1.2 * float(np.ptp(pts[:, :2], axis=0).max())
        if self.render_mode == "rgb_array":
            return self._sim.render(target, distance)
        self._sim.sync_bodies()
        return None

    def close(self):
        sim = getattr(self, "_sim", None)
        if sim is not None:
            sim.close()

    # --- read-only conveniences ------------------------------------------------------------------------
    @property
    def path(self):
        """The current episode's path object (None before the first reset)."""
        return self._path

    @property
    def sim(self) -> Sim:
        return self._sim
