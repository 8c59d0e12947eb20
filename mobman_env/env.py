"""`WheeledPumaEnv`: end-effector path tracking with an arm (default the PUMA 560; also the UR5, the Panda and
a random arm per episode) on a two-wheel differential-drive platform.

Joins the robot (`params`, drawn by `robots.sources`), the engine (`engine`: the kinematic step, the readings,
the task's target, error, reward and observation, for N robots; this env is N = 1 of it, with the state in a
`batch.RobotBatch`), PyBullet in physics mode (`sim`) and the task (`paths`). Imports gymnasium, numpy and those
`mobman_env` modules only. The class keeps its
release 0.1 name (users' scripts and pickles use it); the robot is its `robot` argument.

Following a value by name: the per-episode conditions (`model_error` ... `actuator_tau`) are validated into one
frozen `batch.Conditions` (`env.conditions`; a reset option of the same name replaces one field for an episode),
`RobotBatch.begin` writes each into the `prm` column of its own name (`engine.PRM.actuator_tau`), and the kernels
read it there (`engine._actuate`: `prm[i, PRM.actuator_tau]`). The columns of every engine array are named in
one place, `mobman_env.engine`'s layouts; a step's numbers come back as a `batch.StepResult` under their `info`
names.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping
from dataclasses import replace
from typing import Any, cast

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from mobman_env import engine as E
from mobman_env.batch import CONDITIONS, Conditions, RobotBatch, RobotState
from mobman_env.params import MAX_REL_STD, RobotParams
from mobman_env.paths import TASK_SPECS, Path, validate_spec
from mobman_env.robots.sources import ROBOT_NAMES, RobotSource, robot_source
from mobman_env.sensors import SENSOR_KEYS
from mobman_env.sim import DYNAMICS_MODES, Sim, display_available
from mobman_env.validation import integer, number, vector

#: theta(0) of the paper's section IV, rad.
PAPER_ARM_JOINT_POS = (0.0, math.pi / 4, 0.0, 2 * math.pi / 3, -math.pi / 4, 0.0)
#: Platform pose (x, y, yaw) of P_0 at the start: heading pi faces the paper's circle, which lies towards -x.
PAPER_BASE_POSE = (0.0, 0.0, math.pi)
#: The paper's circle (section IV): radius 0.4 m, tilted pi/6, 20 s, centre towards -x from the start.
PAPER_CIRCLE = TASK_SPECS["circle"]
DEFAULT_REWARD_WEIGHTS = {"tracking": 1.0, "effort": 1e-3}
TIP_ANGLE = E.TIP_ANGLE  # rad, roll or pitch beyond which the platform counts as tipped over

#: observation keys in order: the sensor readings (delayed by `obs_delay`) first, then the task's reference
OBS_KEYS = (*SENSOR_KEYS, "target_pos", "target_vel", "time")
MAX_CONTROL_FREQ = 10_000.0  # Hz
MAX_SUBSTEPS = 1000
MAX_OBS_DELAY = 10_000  # control steps (100 s at 100 Hz): the delay buffer holds this many observations
MAX_WEAR_RATE = 0.1  # 1/s: 10% length change per second; each episode also needs |wear_rate| * duration <= MAX_WEAR
#: the largest relative length change over an episode: a drifting length stays at least a tenth of the episode's
#: (as `RobotParams.perturbed` keeps a worn one at least a tenth of the catalogue's)
MAX_WEAR = 0.9
MAX_ACTUATOR_TAU = 10.0  # s: a lag beyond this is a broken actuator, not a slow one
# per-episode conditions (`batch.CONDITIONS`): constructor arguments that a reset option of the same name overrides
# for one episode
RESET_OPTIONS = ("path", "arm_joint_pos", "base_pose", *CONDITIONS)
__all__ = ["OBS_KEYS", "PAPER_ARM_JOINT_POS", "PAPER_BASE_POSE", "PAPER_CIRCLE", "ROBOT_NAMES", "WheeledPumaEnv"]
_CLOSED = "the env is closed; make a new one with gym.make(...) (or WheeledPumaEnv(...))"


def _condition(name: str, value: Any) -> float | int:
    """Validate one per-episode condition (constructor argument or reset option)."""
    if name == "model_error":
        hint = (
            "the worn robot's lengths are multiplied by factors in [max(0.1, 1 - 3 model_error), 1 + 3 model_error]: "
            "a worn length is at least a tenth of its nominal one; at 1/3 the spread would reach 0"
        )
        return number(name, value, low=0.0, high=MAX_REL_STD, open_high=True, hint=hint)
    if name == "obs_delay":
        return integer(name, value, low=0, high=MAX_OBS_DELAY, hint="control steps")
    if name == "wear_rate":
        return number(name, value, low=-MAX_WEAR_RATE, high=MAX_WEAR_RATE, hint="relative length change per second")
    if name == "actuator_tau":
        return number(name, value, low=0.0, high=MAX_ACTUATOR_TAU, hint="time constant of the actuators' lag, s")
    unit = {"obs_noise": "m", "obs_noise_vel": "m/s", "obs_noise_joint_vel": "rad/s", "obs_noise_yaw": "rad"}[name]
    return number(name, value, low=0.0, hint=f"standard deviation, {unit}")


def _checked(given: Conditions) -> Conditions:
    """The conditions as given to the constructor, each validated (`_condition`, in `CONDITIONS` order)."""
    checked: dict[str, Any] = {k: _condition(k, getattr(given, k)) for k in CONDITIONS}
    return Conditions(**checked)


def _condition_attribute(name: str) -> property:
    """The read-only attribute `name` of the env: its constructor's condition, `env.conditions.<name>`."""
    return property(lambda env: getattr(env.conditions, name), doc=f"The constructor's `{name}` (read-only).")


def _duration(spec: dict) -> float:
    """A validated spec's duration, s (every path type's default is 20 s)."""
    return float(spec.get("duration", 20.0))


#: the platform's start: x and y of P_0 within this many metres of the origin (the observation bounds are 1000 m,
#: and beyond a few km float64 positions lose the sub-micrometre precision the metrics need), yaw in [-2 pi, 2 pi]
MAX_BASE_XY = 100.0


def _base_pose(value: Any) -> np.ndarray:
    pose = vector("base_pose", value, sizes=(3,), hint="x, y of P_0 in m and yaw in rad, e.g. [0, 0, 3.1416]")
    x, y, yaw = pose.tolist()
    if max(abs(x), abs(y)) > MAX_BASE_XY or abs(yaw) > 2 * math.pi:
        raise ValueError(
            f"base_pose {pose.tolist()} is out of range: x and y of P_0 in [-{MAX_BASE_XY:g}, {MAX_BASE_XY:g}] m, yaw "
            f"in [-2 pi, 2 pi] rad; e.g. [0, 0, 3.1416] (move the path instead of the world's origin)"
        )
    return pose


class WheeledPumaEnv(gym.Env):
    r"""Track a time-parameterised path with the end-effector of a wheeled mobile manipulator.

    ## Description
    An arm with n joints stands on a two-wheel differential-drive platform, its base P_c `mount_offset` = 0.1 m
    ahead of the axle centre P_0. `robot` chooses it (`mobman_env.robots.sources`): `"puma560"` (default; the
    standard DH table of Corke & Armstrong-Helouvry, 0.2 m tool, shoulder 0.6 m above the ground, n = 6),
    `"ur5"` (n = 6, standard DH, 0.15 m tool), `"panda"` (n = 7, modified DH, the 0.103 m hand) or `"random"`
    (a new 6-joint arm of `mobman_env.robots.random_arms`' family at every reset: the drawn design is the
    episode's nominal robot). The agent commands the speeds of the n arm joints and the 2 wheels; the task is to
    keep the end-effector point r_a on a desired path r_d(t) that is fixed in the world and starts where the
    end-effector starts (the initial error is 0). This is the task of "Neural-Network-Based Control of Wheeled
    Mobile Manipulators with Unknown Kinematic Models" (section IV). Each reset draws a "worn" true robot whose
    link lengths, tool, wheel radius, half track and mount offset differ from the catalogue by `model_error`
    (relative std), so model-based controllers that use `nominal_params` make errors, as in the paper.

    ## Action Space
    `Box(-1, 1, (n + 2,), float32)`, scaled by `action_scale` (rad/s) to joint and wheel speeds; for the PUMA
    (n = 6, 8 actuators):

    | index | actuator | scale (rad/s) |
    |---|---|---|
    | 0-2 | arm joints 1-3 | 3.0 |
    | 3-5 | arm joints 4-6 (joint 6 turns about the tool axis: it never moves the point) | 5.0 |
    | 6 | left wheel (+y side) | 10.0 (2 m/s rim speed) |
    | 7 | right wheel (-y side) | 10.0 |

    Any robot: indices 0 to n-1 are the arm joints at the description's speed limits (UR5: 3.15 rad/s joints
    1-3, 3.2 rad/s 4-6; Panda: 2.175 rad/s joints 1-4, 2.61 rad/s 5-7; random arms: the PUMA's), n and n + 1
    the left and right wheel at 10 rad/s.

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
    | base_yaw | (1,) | platform heading phi, continuous (not wrapped) (+ `obs_noise_yaw`) | rad |
    | joint_pos | (n + 2,) | n arm joint angles, left and right wheel angles | rad |
    | joint_vel | (n + 2,) | their speeds (+ `obs_noise_joint_vel`) | rad/s |
    | target_pos | (3,) | desired position r_d(t) | m |
    | target_vel | (3,) | desired velocity r_d_dot(t) | m/s |
    | time | (1,) | time since reset t | s |

    Sensor model (`mobman_env.sensors`): independent Gaussian noise of the stds above, drawn from the env's
    `np_random` each step (nothing is drawn for a std of 0). Typical magnitudes of real mobile manipulators:
    heading from wheel odometry fused with an IMU gyro drifts and jitters by about 1-5 mrad (1 sigma) over seconds
    (e.g. Borenstein & Feng, "Measurement and correction of systematic odometry errors in mobile robots", IEEE
    TRA 12(6), 1996; MEMS gyros' angle random walk of 0.1-0.5 deg/sqrt(h) integrated over a control period), so
    `obs_noise_yaw` 1e-3 rad is a good sensor and 5e-3 rad a poor one. With `obs_delay` = k the seven sensor keys (ee_pos
    to joint_vel) are the noisy readings of k control steps ago (the reset reading until k steps have passed);
    target_pos, target_vel and time are the task's reference at the current time (a controller knows its own
    clock; delaying it too would only shift the task in time). `info["ee_pos_true"]` and
    `info["tracking_error"]` are always noise-free, undelayed and of the current (worn) robot.

    ## Actuators
    Each actuator's realised speed follows its command through a first-order lag of time constant
    `actuator_tau` (s; 0: instantly), u(t_k+1) = u_c + (u(t_k) - u_c) e^{-dt/tau}, discretised exactly: the joint
    and wheel angles move by the exact integral of u over the step (kinematic mode; the platform's arc uses the
    wheels' mean speeds over the step), and in physics mode the velocity motors are given that mean speed.
    `joint_vel` reports the realised speed. Typical magnitudes: a joint or wheel velocity loop of bandwidth f_c
    lags like tau = 1 / (2 pi f_c); electric drives' velocity loops close at roughly 5-30 Hz, i.e. tau of 5-30 ms
    (Siciliano, Sciavicco, Villani, Oriolo, *Robotics: Modelling, Planning and Control*, Springer 2009, ch. 8 on
    the drives' velocity loops), and a heavy base with its wheel drives behaves slower still. The joint-limit rule acts on the
    command (a joint at its limit whose command pushes further gets 0) and on the motion (a joint that reaches
    its limit inside a step stops there, its realised speed 0).

    ## Robot wear
    Each reset draws the episode's true robot (`model_error`). With `wear_rate` = w != 0 its lengths (the
    arm's non-zero DH a and d, e.g. the PUMA's a2, a3, d3, d4; tool, wheel radius, half track, mount offset)
    then drift linearly during the episode:
    length(t) = length(0) (1 + w t), updated once per control step (the robot of time t_k acts during the step
    from t_k to t_k+1; the state at t is the forward kinematics of the robot of t). Kinematic mode only: a loaded
    PyBullet body cannot change its link lengths. Re-creating it mid-episode costs about 8.5 ms (a fresh world
    and URDF load, CPU time measured) against 0.24 ms per physics step, i.e. 35x slower if done every step; done
    every second instead, the lengths would jump by w per reload (5 mm at 1 m for w = 0.005 1/s) and contacts
    would be teleported. So physics mode refuses w != 0. An episode needs |w| * duration <= 0.9 (a length stays at
    least a tenth of the episode's). `true_params` is the robot of the current time; `info["true_params_hash"]` stays that of the
    episode's robot at t = 0. The engine scales the lengths inside its step (2n + 4 products: no measurable cost).

    ## Rewards
    Named terms, reported in `info["reward_terms"]` and summed exactly:
    `tracking = -w_tracking * ||r_d - r_a||` (m, noise-free) and `effort = -w_effort * ||a||^2` (a: the
    normalised action after clipping). Weights from `reward_weights` (default tracking 1.0, effort 1e-3).

    ## Starting State
    Arm at `arm_joint_pos` (default the robot's start, `mobman_env.robots.starts.STARTS`: for the PUMA the
    paper's theta(0) = [0, pi/4, 0, 2pi/3, -pi/4, 0] rad; a random arm starts where its draw says), wheels at 0 rad,
    platform at `base_pose` (x, y of P_0 in m, yaw in rad; default [0, 0, pi]), at rest. The path starts at the
    end-effector. Reset options override the constructor argument of the same name for one episode: `"path"`
    (spec dict), `"arm_joint_pos"` (n or n + 2 numbers; not with `robot="random"`), `"base_pose"` (3 numbers) and the conditions
    `"model_error"`, `"obs_noise"`, `"obs_noise_vel"`, `"obs_noise_joint_vel"`, `"obs_noise_yaw"`, `"obs_delay"`,
    `"wear_rate"`, `"actuator_tau"` (validated as in the constructor). `info["task"]` echoes the path spec, its start, the joint vector and the
    base pose; `info["true_params_hash"]` identifies the true robot.

    ## Episode End
    Truncated when t reaches the path's duration (no `max_episode_steps`: 2000 steps for 20 s at 100 Hz).
    Terminated if the platform tips over (roll or pitch > 30 deg) or, when `error_bound` (m) is set, the
    tracking error exceeds it.

    ## Arguments
    | argument | default | meaning |
    |---|---|---|
    | path | None | path spec dict (see `mobman_env.paths`); None: the paper's circle |
    | arm_joint_pos | None | n arm angles (or n + 2 with wheels), rad; None: the robot's start (PUMA: the paper's theta(0)) |
    | base_pose | None | (x, y, yaw) of P_0, m and rad; None: (0, 0, pi) |
    | dynamics | "physics" | "physics" (PyBullet contact dynamics) or "kinematic" (the paper's ideal model) |
    | control_freq | 100.0 | control steps per second, Hz |
    | n_substeps | 2 | PyBullet steps per control step (physics mode) |
    | model_error | 0.05 | relative std of the true robot's kinematic lengths vs the nominal ones, in [0, 1/3) |
    | obs_noise | 0.0 | std of the Gaussian noise on ee_pos and arm_base_pos, m |
    | obs_noise_vel | 0.0 | std of the Gaussian noise on ee_vel and arm_base_vel, m/s |
    | obs_noise_joint_vel | 0.0 | std of the Gaussian noise on joint_vel, rad/s |
    | obs_noise_yaw | 0.0 | std of the Gaussian noise on base_yaw, rad |
    | obs_delay | 0 | age of the sensor readings in the observation, control steps, in [0, 10000] |
    | wear_rate | 0.0 | relative change per second of the true robot's lengths, 1/s, in [-0.1, 0.1]; kinematic mode |
    | actuator_tau | 0.0 | time constant of every actuator's first-order lag, s, in [0, 10]; both modes |
    | reward_weights | None | dict with keys "tracking", "effort"; None: {"tracking": 1.0, "effort": 1e-3} |
    | error_bound | None | terminate when the tracking error exceeds this, m; None: never |
    | render_mode | None | None, "rgb_array" (headless TinyRenderer) or "human" (window; see Rendering) |
    | robot | "puma560" | the arm: "puma560", "ur5", "panda" or "random" (a new arm per reset) |

    Numbers are checked by `mobman_env.validation`: bools, strings and complex numbers are refused. Also
    `control_freq` in (0, 10000] Hz and `n_substeps` in [1, 1000]; path specs have documented ranges
    (`mobman_env.paths.validate_spec`).

    ## Rendering
    `metadata["render_fps"]` is the env's control frequency (per instance), so one frame per step plays in real
    time, e.g. through `gymnasium.wrappers.RecordVideo`. `"rgb_array"` works headless (TinyRenderer). `"human"`
    opens PyBullet's window; without a display (neither DISPLAY nor WAYLAND_DISPLAY set) a GUI connection would
    kill the process, so the env warns (naming `"rgb_array"`), runs headless with no window, and `render()`
    returns None and draws nothing (so `gymnasium.utils.env_checker.check_env` with its defaults passes
    headless). In kinematic mode with `wear_rate` != 0 every rendered frame reloads the body of the current
    robot (about 8.5 ms per frame), so the picture is the true robot of that time.

    ## Privileged attributes
    `nominal_params` (the catalogue robot, or the episode's drawn design for `robot="random"`: what a
    model-based method may know) and `true_params` (the current
    true robot: for oracles and tests only) are the documented doors to robot models; `true_actuator_tau` (the
    episode's lag, s) is the door to the actuators' for the same readers (`mpc-oracle`). `sim` also holds the true
    robot (the PyBullet body, the kinematic state), so reading it goes through `true_params` too: a guard that
    makes `true_params` raise covers it. The generated URDF is deleted as soon as PyBullet has loaded it. Names
    with a leading underscore are not an interface.

    ## Version History
    * v0: initial release. Release 0.2 (same ids, bit-identical at the default options): `obs_noise_joint_vel`,
      `obs_delay`, `wear_rate`; conditions as reset options; `model_error` < 1/3; path ranges; render_fps =
      control frequency; headless "human" warns instead of raising; step/reset after close() raise; `robot`
      (UR5, Panda, random arms: ids `Wheeled{UR5,Panda,RandomArm}-*-v0`; the PUMA ids unchanged).
    * v0, release 0.3 (same ids): the step is `mobman_env.engine`'s kernel (written once, compiled, BLAS-free), so
      the bits of every result changed once (last-bit changes; chaotic closed loops differ beyond that; the
      CHANGELOG lists what moved); `actuator_tau` and `obs_noise_yaw`; physics mode computes the end-effector from
      the joint states and base pose (PyBullet's own within 1e-9 m); kinematic mode opens no PyBullet client
      unless it renders; `state()`.
    """

    # render_fps: the default control frequency; each instance assigns its own dict (its control frequency), the
    # class dict is never mutated. Not a ClassVar: gymnasium.Env declares `metadata` as an instance attribute.
    metadata: dict[str, Any] = {"render_modes": ["human", "rgb_array"], "render_fps": 100.0}  # noqa: RUF012
    # the constructor's conditions, read from `conditions` (one frozen `batch.Conditions`)
    model_error = _condition_attribute("model_error")
    obs_noise = _condition_attribute("obs_noise")
    obs_noise_vel = _condition_attribute("obs_noise_vel")
    obs_noise_joint_vel = _condition_attribute("obs_noise_joint_vel")
    obs_noise_yaw = _condition_attribute("obs_noise_yaw")
    obs_delay = _condition_attribute("obs_delay")
    wear_rate = _condition_attribute("wear_rate")
    actuator_tau = _condition_attribute("actuator_tau")

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
        obs_noise_joint_vel: float = 0.0,
        obs_noise_yaw: float = 0.0,
        obs_delay: int = 0,
        wear_rate: float = 0.0,
        actuator_tau: float = 0.0,
        reward_weights: dict | None = None,
        error_bound: float | None = None,
        render_mode: str | None = None,
        robot: str = "puma560",
    ):
        self._source: RobotSource = robot_source(robot)
        self.robot = robot
        if dynamics not in DYNAMICS_MODES:
            raise ValueError(f"unknown dynamics mode {dynamics!r}; accepted: {', '.join(DYNAMICS_MODES)}")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"unknown render_mode {render_mode!r}; accepted: None, 'rgb_array', 'human'")
        control_freq = number("control_freq", control_freq, low=0.0, high=MAX_CONTROL_FREQ, open_low=True, hint="Hz")
        n_substeps = integer("n_substeps", n_substeps, low=1, high=MAX_SUBSTEPS)
        #: the episode's conditions (each reset's, unless a reset option of the same name overrides it)
        self.conditions = _checked(
            Conditions(
                model_error, obs_noise, obs_noise_vel, obs_noise_joint_vel, obs_noise_yaw, obs_delay, wear_rate,
                actuator_tau,
            )
        )  # fmt: skip
        if error_bound is not None:
            error_bound = number("error_bound", error_bound, low=0.0, hint="m; None: never terminate on the error")
        self.reward_weights = _reward_weights(reward_weights)
        self.error_bound = error_bound
        self.path_spec = validate_spec(PAPER_CIRCLE if path is None else path)
        self._check_wear(dynamics, self.conditions.wear_rate, _duration(self.path_spec))
        self._nominal_params = self._source.nominal
        if arm_joint_pos is None:
            start = self._source.default_start
            self.arm_joint_pos: np.ndarray | None = (
                None if start is None else self._joint_vector(start, self._nominal_params)
            )
        else:
            self.arm_joint_pos = self._joint_vector(arm_joint_pos, self._nominal_params)
        self.base_pose = _base_pose(PAPER_BASE_POSE if base_pose is None else base_pose)
        self.dynamics = dynamics
        self.control_freq = control_freq
        self.dt = 1.0 / control_freq
        self.n_substeps = n_substeps
        self.render_mode = render_mode
        # per instance, the class dict untouched: one frame per control step plays in real time
        self.metadata = {**type(self).metadata, "render_fps": control_freq}

        self.action_scale = self._nominal_params.action_scale
        self.n_actuators = self._nominal_params.n_actuators
        self.action_space = spaces.Box(-1.0, 1.0, (self.n_actuators,), np.float32)
        self.observation_space = self._make_observation_space(self.n_actuators)
        # one flat float32 vector per step, handed out as views, in OBS_KEYS order
        self._obs_slices = _flat_layout(self.observation_space)
        window = _gui_window(render_mode)
        # the path is drawn (as markers) only where it can be seen
        self._draws = render_mode == "rgb_array" or window
        # the engine's state of this one robot (N = 1); PyBullet steps it in physics mode and renders it in both
        self._batch = RobotBatch(1, self.n_actuators - 2, self.dt, self.reward_weights, error_bound)
        self._rows = self._batch.rows
        self._rngs: list[np.random.Generator] = []
        self._physics = dynamics == "physics"
        self._sim: Sim | None = Sim(self.dt, n_substeps, gui=window) if (self._physics or render_mode) else None
        self._closed = False
        self._path: Path | None = None
        self._started = False
        self._task: dict = {}
        self._params_hash = ""

    # --- construction helpers --------------------------------------------------------------------------
    @staticmethod
    def _check_wear(dynamics: str, wear_rate: float, duration: float) -> None:
        if wear_rate != 0.0 and dynamics != "kinematic":
            raise ValueError(
                f"wear_rate={wear_rate!r} needs dynamics='kinematic': a loaded PyBullet body cannot change its link "
                "lengths (use wear_rate=0.0 in physics mode)"
            )
        if abs(wear_rate) * duration > MAX_WEAR:
            raise ValueError(
                f"wear_rate={wear_rate!r} over a {duration:g} s path would take a length below a tenth of the "
                f"episode's: |wear_rate| * duration must stay <= {MAX_WEAR} (here |wear_rate| <= "
                f"{MAX_WEAR / duration:.4g} 1/s)"
            )

    def _joint_vector(self, value: Any, nominal: RobotParams) -> np.ndarray:
        if self._source.start_is_drawn:
            raise ValueError(
                f"arm_joint_pos={value!r}: robot={self.robot!r} draws each arm with its own start (away from "
                "singularities and limits); leave arm_joint_pos unset, or use a fixed robot such as 'ur5'"
            )
        n = nominal.n_joints
        example = self._source.default_start or PAPER_ARM_JOINT_POS
        arr = vector(
            "arm_joint_pos",
            value,
            sizes=(n, n + 2),
            hint=f"{n} arm angles or {n + 2} (arm + left, right wheel) in rad, e.g. {np.round(example, 4).tolist()}",
        )
        if arr.shape == (n,):
            arr = np.concatenate([arr, [0.0, 0.0]])
        lo, hi = np.array(nominal.joint_lower), np.array(nominal.joint_upper)
        if np.any(arr[:n] < lo) or np.any(arr[:n] > hi):
            raise ValueError(
                f"arm_joint_pos {arr[:n].tolist()} is outside the joint limits of {nominal.arm.name}: lower "
                f"{np.round(lo, 4).tolist()}, upper {np.round(hi, 4).tolist()} (rad)"
            )
        return arr

    @staticmethod
    def _make_observation_space(n_act: int = 8) -> spaces.Dict:
        f32 = np.float32
        # the engine clips every entry into these bounds (m and m/s: wide enough for any physics overshoot)
        big_pos, big_vel = E.BIG_POS, E.BIG_VEL

        def box(n, lim):
            return spaces.Box(-lim, lim, (n,), f32)

        return spaces.Dict(
            {
                "ee_pos": box(3, big_pos),
                "ee_vel": box(3, big_vel),
                "arm_base_pos": box(2, big_pos),
                "arm_base_vel": box(2, big_vel),
                "base_yaw": box(1, E.BIG_ANGLE),
                "joint_pos": box(n_act, E.BIG_ANGLE),
                "joint_vel": box(n_act, E.BIG_JOINT_VEL),
                "target_pos": box(3, big_pos),
                "target_vel": box(3, big_vel),
                "time": spaces.Box(0.0, E.BIG_TIME, (1,), f32),
            }
        )

    def _check_open(self) -> None:
        if self._closed:
            raise RuntimeError(_CLOSED)

    def _episode_settings(
        self, options: Any, nominal: RobotParams, dynamics: str
    ) -> tuple[dict, np.ndarray | None, np.ndarray, Conditions]:
        """The checked reset options over this env's own settings: (path spec, arm start or None when the
        robot draws its start, base pose, conditions). The vector env resolves its rows' resets through this
        too, with `dynamics` "kinematic"."""
        if options is not None and not isinstance(options, Mapping):
            raise ValueError(
                f"reset options must be a dict such as {{'path': {{'type': 'circle', 'radius': 0.2}}}}, "
                f"got {options!r}; accepted keys: {', '.join(map(repr, RESET_OPTIONS))}"
            )
        options = dict(options or {})
        unknown = sorted(set(options) - set(RESET_OPTIONS), key=str)
        if unknown:
            raise ValueError(f"unknown reset option(s) {unknown}; accepted: {', '.join(map(repr, RESET_OPTIONS))}")
        spec = validate_spec(options["path"]) if "path" in options else self.path_spec
        q0: np.ndarray | None
        if "arm_joint_pos" in options:
            q0 = self._joint_vector(options["arm_joint_pos"], nominal)
        else:
            q0 = self.arm_joint_pos
        pose = _base_pose(options["base_pose"]) if "base_pose" in options else self.base_pose
        overrides: dict[str, Any] = {k: _condition(k, options[k]) for k in CONDITIONS if k in options}
        cond = replace(self.conditions, **overrides)
        self._check_wear(dynamics, cond.wear_rate, _duration(spec))
        return spec, q0, pose, cond

    # --- gym API ---------------------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        self._check_open()
        if isinstance(seed, bool):  # gymnasium would take True as seed 1
            raise ValueError(f"seed must be None or an integer >= 0, got {seed!r}")
        super().reset(seed=seed)
        spec, q0, pose, cond = self._episode_settings(options, self._nominal_params, self.dynamics)
        rng = self.np_random
        self._rngs = [rng]
        b, rows = self._batch, self._rows
        # one RNG stream, in a fixed order: the arm and its start (random family only), the true robot, then the
        # path's own seed, then sensor noise
        self._nominal_params, q0 = b.begin_episode(0, rng, self._source, self._nominal_params, q0, pose, cond)
        if self._physics:
            assert self._sim is not None
            self._sim.reset(b.params0[0], q0, pose)
            b.io[0, b.IO.phys_q : b.IO.reward] = self._sim.read()  # the PyBullet readings (`io_columns`' phys_*)
            ee = b.ee_physics(rows)
        else:
            ee = b.ee_kinematic(rows)
        self._path = path = b.set_path(0, spec, ee[0], rng, self.control_freq)
        self._started = True
        self._params_hash = b.hashes[0]
        self._task = b.task(0, ee[0], q0, pose)
        if self._draws:
            assert self._sim is not None
            ts = np.linspace(0.0, path.duration, 60)
            self._path_points = np.array([path.position(t) for t in ts])
            self._sim.draw_path(self._path_points)
        b.draw_noise(rows, self._rngs)
        flat = b.new_obs()
        if self._physics:
            b.observe_physics(rows, flat, False)
        else:
            b.observe_kinematic(rows, flat)
        info = {
            "task": self._task,
            "true_params_hash": self._params_hash,
            "ee_pos_true": ee[0].copy(),
            "tracking_error": 0.0,
            "n_clipped": 0,
            "joint_limit_hits": 0,
        }
        return self._obs_dict(flat[0]), info

    def step(self, action):
        self._check_open()
        if not self._started:
            raise RuntimeError("call reset() before step()")
        b = self._batch
        b.io[0, b.IO.action : b.IO.action + self.n_actuators] = self._checked_action(action)
        b.draw_noise(self._rows, self._rngs)
        flat = b.new_obs()
        if self._advance(flat) >= 0:
            al = np.asarray(action, dtype=float)
            raise ValueError(
                f"action must be finite, got {al.tolist()} (NaN or inf at {np.flatnonzero(~np.isfinite(al)).tolist()})"
            )
        r = b.result(0)
        info = {
            "ee_pos_true": r.ee_pos_true,
            "tracking_error": r.tracking_error,
            "reward_terms": {"tracking": r.tracking, "effort": r.effort},
            "action_clipped": r.action_clipped,
            "n_clipped": r.n_clipped,
            "joint_limit_hits": r.joint_limit_hits,
            "tipped_over": r.tipped_over,
            "true_params_hash": self._params_hash,
        }
        return self._obs_dict(flat[0]), r.reward, r.terminated, r.truncated, info

    def _checked_action(self, action: Any) -> np.ndarray:
        """The action as an array of shape (m,) of real numbers (finiteness is the kernel's check)."""
        m = self.n_actuators
        if type(action) is np.ndarray and action.shape == (m,) and action.dtype.kind == "f":
            return action
        a = np.asarray(action)
        if a.dtype.kind not in "fiu":
            raise ValueError(
                f"action must be real numbers (a float array of shape ({m},)), got dtype {a.dtype} "
                f"({'complex: the imaginary part would be lost' if a.dtype.kind == 'c' else 'not a number type'})"
            )
        if a.shape != (m,):
            raise ValueError(
                f"action must have shape ({m},) ({m - 2} arm joints, left wheel, right wheel), got shape {a.shape}"
            )
        return a

    def _advance(self, flat: np.ndarray) -> int:
        """One step of the robot (its action in the batch's `io`), the observation into `flat`: the kinematic
        kernel, or the motors' commands, PyBullet's step and the readings of its state. -1, or 0 when the action
        is not finite (then nothing moved)."""
        b, rows = self._batch, self._rows
        if not self._physics:
            return b.step_kinematic(rows, flat)
        bad = E.command_physics(b.arm, b.prm, b.st, b.io, b.dt, rows)
        if bad < 0:
            sim = self._sim
            assert sim is not None
            c = b.IO
            sim.command(b.io[0, c.motor_speed : c.motor_speed + self.n_actuators].tolist())
            b.io[0, c.phys_q : c.reward] = sim.read()  # the PyBullet readings (`io_columns`' phys_*)
            b.observe_physics(rows, flat, True)
        return bad

    def _obs_dict(self, flat: np.ndarray) -> dict:
        """The observation dict: views of one flat float32 vector, in OBS_KEYS order."""
        return {k: flat[sl] for k, sl in self._obs_slices}

    def state(self) -> RobotState:
        """The noise-free state after the last reset or step (what the sensors saw before noise and delay). It
        holds the true robot's end-effector, so it is reached through `true_params` (a guard on it covers this
        door); for tests and diagnostics."""
        self.true_params  # noqa: B018 - the one door to the true robot, so that a guard on it sees this access
        return self._batch.state(0)

    def render(self):
        self._check_open()
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; make the env with render_mode='rgb_array'")
            return None
        if self._path is None:
            raise RuntimeError("call reset() before render()")
        if not self._draws:  # "human" without a display: nothing to draw into
            return None
        sim = self._sim
        assert sim is not None
        b = self._batch
        st = b.st[0]
        S = b.S
        if not self._physics:  # the body where the engine's state is (the robot of the current time)
            sim.show(b.true_params(0), st[S.q : S.q + self.n_actuators], st[[S.x, S.y, S.yaw]])
        # look at the middle of the box holding the path and the platform
        base = st[[S.x, S.y]]
        pts = np.vstack([self._path_points, [base[0], base[1], 0.3], [base[0], base[1], 1.0]])
        target = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
        distance = 1.2 + 1.2 * float(np.ptp(pts[:, :2], axis=0).max())
        if self.render_mode == "rgb_array":
            return sim.render(target, distance)
        return None

    def close(self):
        """Disconnect the simulation and delete its temporary files; safe to call twice. `reset`, `step` and
        `render` raise `RuntimeError` afterwards."""
        self._closed = True
        sim = getattr(self, "_sim", None)
        if sim is not None:
            sim.close()

    # --- the documented doors to robot models ----------------------------------------------------------
    @property
    def nominal_params(self) -> RobotParams:
        """The catalogue robot (`RobotParams.nominal(arm)`; for `robot="random"` the episode's drawn design):
        what a model-based controller may know."""
        return self._nominal_params

    @property
    def true_params(self) -> RobotParams:
        """The true robot at the current time of the episode (the one drawn at reset, drifted by `wear_rate`;
        the nominal robot before the first reset). For oracles and tests only; it never appears in `info`."""
        if not self._started:
            return self._nominal_params
        return self._batch.true_params(0)

    @property
    def true_actuator_tau(self) -> float:
        """The time constant of the episode's actuator lag, s: the `actuator_tau` condition the episode runs
        under (a reset option included; the constructor's before the first reset). Part of the true model: for
        oracles (`mpc-oracle`) and tests only; it never appears in `info`."""
        if not self._started:
            return float(self.conditions.actuator_tau)
        return float(self._batch.prm[0, E.PRM.actuator_tau])

    # --- read-only conveniences ------------------------------------------------------------------------
    @property
    def path(self) -> Path | None:
        """The current episode's path object (None before the first reset)."""
        return self._path

    @property
    def sim(self) -> Sim | None:
        """The PyBullet world (physics mode; kinematic mode: only with a render_mode, else None). It holds the true
        robot, so it is reached through `true_params`: a guard on `true_params` covers it. For tests and the speed
        benchmark."""
        self.true_params  # noqa: B018 - the one door to the true robot, so that a guard on it sees this access
        return self._sim


def _reward_weights(reward_weights: dict | None) -> dict[str, float]:
    """The reward weights: the defaults, overridden by the given ones (known keys, numbers >= 0)."""
    weights = dict(DEFAULT_REWARD_WEIGHTS)
    if reward_weights is not None:
        if not isinstance(reward_weights, dict) or set(reward_weights) - set(DEFAULT_REWARD_WEIGHTS):
            raise ValueError(
                f"reward_weights must be a dict with keys from {sorted(DEFAULT_REWARD_WEIGHTS)}, got {reward_weights!r}"
            )
        weights.update({k: number(f"reward_weights[{k!r}]", v, low=0.0) for k, v in reward_weights.items()})
    return weights


def _flat_layout(space: spaces.Dict) -> list[tuple[str, slice]]:
    """Where each observation key sits in the flat float32 vector (OBS_KEYS order; the engine's layout)."""
    sizes = [cast(spaces.Box, space[k]).shape[0] for k in OBS_KEYS]
    ends = np.cumsum(sizes)
    return [(k, slice(int(e) - n, int(e))) for k, n, e in zip(OBS_KEYS, sizes, ends)]


def _gui_window(render_mode: str | None) -> bool:
    """Whether to open PyBullet's GUI: `render_mode="human"` with a display; without one, warn and run
    headless (a GUI connect without a display kills the process)."""
    window = render_mode == "human" and display_available()
    if render_mode == "human" and not window:
        warnings.warn(
            "render_mode='human' needs a display (neither DISPLAY nor WAYLAND_DISPLAY is set; PyBullet's GUI "
            "would kill the process): running headless with no window, render() returns None; use "
            "render_mode='rgb_array' for frames without a display",
            UserWarning,
            stacklevel=3,
        )
    return window
