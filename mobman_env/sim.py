"""The simulation behind one env: one PyBullet client, the robot body, and the two dynamics modes.

* `"physics"`: velocity-controlled motors with torque limits (`RobotParams.*_torque_limit`); the platform moves
  by wheel contact and friction, the casters are frictionless. One control step = `n_substeps` PyBullet steps.
* `"kinematic"`: the paper's idealised model. Joint and wheel angles are integrated exactly from the commanded
  speeds and the platform pose from the no-slip unicycle model (`kinematics.integrate_unicycle`). No PyBullet
  call is made per step; the bodies are synced only to render.

Joint limits are enforced in both modes: a command that would push a joint past its limit is replaced by 0 for
that joint (kinematic mode also clamps the angle to the limit), and each such event is counted.

Every PyBullet call goes to this sim's own client (`self.client`, or pybullet's functions with its
`client_id`); `close()` is safe to call twice. The body moves only through `Sim`'s methods.

Per physics step (the env's hot path): one motor command, `n_substeps` x `stepSimulation`, and one read of the
body (`readings()`: joint states, end-effector link state with velocity, base pose and velocity) into plain
floats; the arm angles the limit check needs are the last read's (the env reads after every step; a reset or a
step without a read in between reads them afresh). Small fixed-size math (limits, p_c, yaw) is written out in
floats; `state()` builds the `RobotState` arrays from the same read.

Bodies and files. The robot body changes only when the robot does (a new true robot per seed): the world is
then rebuilt with `resetSimulation()` (removing a body alone leaves about 8 KiB of PyBullet memory behind per
load, and PyBullet's file cache another 8 KiB per URDF path: measured; it is off for generated files), so
nothing accumulates over any number of resets (under 0.1 KiB per reload, measured). A perturbed robot's URDF is written to
`<tmp>/mobman-urdf-pid<PID>-<random>/robot.urdf`, loaded and deleted at once (PyBullet keeps no reference to
it), so the folder is empty between loads and the file is never there for a policy to read; the folder goes on
`close()`. Folders left by killed processes (SIGKILL runs no cleanup) are removed when a new one is made: those
of this user whose PID is no longer running (POSIX only; on Windows they are left alone).

The true robot is kept under the private name `_params`; the env's `true_params` is its one documented door.
"""

from __future__ import annotations

import contextlib
import math
import os
import re
import shutil
import sys
import tempfile
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mobman_env import kinematics as K
from mobman_env import urdf
from mobman_env.params import RobotParams

DYNAMICS_MODES = ("physics", "kinematic")
GRAVITY = 9.81  # m/s^2
#: temporary URDF folders are named `<URDF_DIR_PREFIX><pid>-<random>` in the system's temporary directory
URDF_DIR_PREFIX = "mobman-urdf-pid"
_URDF_DIR_RE = re.compile(re.escape(URDF_DIR_PREFIX) + r"(\d+)-")


def _libc_fflush() -> None:
    try:
        import ctypes

        ctypes.CDLL(None).fflush(None)
    except Exception:  # pragma: no cover - platforms without a C library handle
        pass


@contextmanager
def _quiet_stdout():
    """Keep PyBullet's C-level banners ("pybullet build time", "argv[0]=") off our stdout."""
    try:
        fd = sys.stdout.fileno()
    except (AttributeError, ValueError, OSError):  # e.g. pytest capture without a real fd
        yield
        return
    sys.stdout.flush()
    saved = os.dup(fd)
    try:
        with open(os.devnull, "w") as devnull:
            os.dup2(devnull.fileno(), fd)
        yield
    finally:
        _libc_fflush()
        os.dup2(saved, fd)
        os.close(saved)


with _quiet_stdout():
    import pybullet
    import pybullet_data
    from pybullet_utils import bullet_client


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # e.g. PermissionError: it exists, owned by someone else
        return True
    return True


def remove_stale_urdf_dirs(tmp: str | None = None) -> list[str]:
    """Remove the temporary URDF folders (`URDF_DIR_PREFIX<pid>-...`) of this user whose process is gone, e.g.
    after a SIGKILL; returns the removed paths. POSIX only (on Windows `os.kill(pid, 0)` would end the process):
    returns [] there. A folder of a live process in another PID namespace may be removed too: harmless, `Sim`
    recreates its folder before every write."""
    if os.name != "posix":
        return []
    tmp = tmp or tempfile.gettempdir()
    removed = []
    try:
        entries = list(os.scandir(tmp))
    except OSError:
        return []
    for entry in entries:
        m = _URDF_DIR_RE.match(entry.name)
        if not m or int(m.group(1)) == os.getpid():
            continue
        try:
            if not entry.is_dir(follow_symlinks=False) or entry.stat(follow_symlinks=False).st_uid != os.getuid():
                continue
        except OSError:
            continue
        if not _pid_alive(int(m.group(1))):
            shutil.rmtree(entry.path, ignore_errors=True)
            removed.append(entry.path)
    return removed


@dataclass
class RobotState:
    """What the sensors see (noise-free), world frame, SI units."""

    ee_pos: np.ndarray  # (3,) m
    ee_vel: np.ndarray  # (3,) m/s
    arm_base_pos: np.ndarray  # (2,) m, p_c
    arm_base_vel: np.ndarray  # (2,) m/s
    base_pose: np.ndarray  # (3,) x, y of P_0 (m), yaw (rad, continuous)
    joint_pos: np.ndarray  # (n + 2,) rad: n arm joints, left wheel, right wheel
    joint_vel: np.ndarray  # (n + 2,) rad/s
    roll_pitch: tuple[float, float]  # rad, of the platform


def display_available() -> bool:
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


class Sim:
    """One PyBullet client and the robot in it."""

    def __init__(self, dynamics: str, dt: float, n_substeps: int, gui: bool = False):
        if dynamics not in DYNAMICS_MODES:
            raise ValueError(f"unknown dynamics mode {dynamics!r}; accepted: {', '.join(DYNAMICS_MODES)}")
        if gui and not display_available():
            raise RuntimeError(
                "render_mode='human' needs a display (DISPLAY is not set) and PyBullet's GUI would kill the "
                "process without one; use render_mode='rgb_array' for headless rendering"
            )
        self.dynamics = dynamics
        self.dt = float(dt)
        self.n_substeps = int(n_substeps)
        self.gui = bool(gui)
        self._tmpdir: str | None = None
        self._closed = False
        with _quiet_stdout():
            self.client = bullet_client.BulletClient(connection_mode=pybullet.GUI if gui else pybullet.DIRECT)
        self.client_id = self.client._client
        # the per-step calls of physics mode skip BulletClient.__getattr__, which builds a new partial per call
        # (0.7 us each, measured): the motor command is the client's partial, bound once; the reads and
        # stepSimulation are pybullet's functions called with this client's id as a positional argument
        # (0.3-0.5 us less per call than a partial with keywords, measured)
        self._motor_array = self.client.setJointMotorControlArray
        self.client.setAdditionalSearchPath(pybullet_data.getDataPath())
        self.body: int | None = None
        self._body_hash: str | None = None
        self._markers: list[int] = []
        self._marker_points = np.empty((0, 3))
        self._marker_shape: int | None = None
        self._params = RobotParams.nominal()  # replaced by reset(); no body exists before it
        self._has_robot = False
        #: torque limits of the n + 2 actuators (n arm joints, left, right wheel), N m (set by reset)
        self.torque_limits: list[float] = []
        self._build_world()
        # kinematic-mode state (sized by reset for the robot's n + 2 actuators)
        self._n = self._params.n_joints
        self._q = np.zeros(self._n + 2)
        self._pose = np.zeros(3)
        self._u = np.zeros(self._n + 2)
        self._yaw = 0.0  # continuous yaw tracked in physics mode
        #: physics mode: the arm angles of the last read, None once anything may have moved the body since
        self._q_arm: list[float] | None = None
        self._synced = False

    @property
    def params(self) -> RobotParams:
        raise AttributeError(
            "Sim.params is not public: the true robot is read through the env's documented door, "
            "env.unwrapped.true_params (for oracles and tests only)"
        )

    # --- world and body --------------------------------------------------------------------------------
    def _build_world(self) -> None:
        """Gravity, time step, solver settings and the ground plane of an empty world (a fresh client's, or
        after `resetSimulation()`, which clears all of them)."""
        c = self.client
        c.setGravity(0, 0, -GRAVITY)
        c.setTimeStep(self.dt / self.n_substeps)
        # 100 solver iterations (default 50): the zero-command creep of the velocity motors drops ~3x (measured)
        c.setPhysicsEngineParameter(numSubSteps=0, numSolverIterations=100, deterministicOverlappingPairs=1)
        self.plane = self._load_urdf("plane.urdf", [0, 0, 0], cache=True)
        c.changeDynamics(self.plane, -1, lateralFriction=1.0)

    def _load_urdf(self, path: str, position: list, cache: bool, flags: int = 0) -> int:
        """loadURDF with PyBullet's file cache on only for files that never change (the plane, the shipped
        nominal robot: their meshes are then read once, 5 ms -> 0.4 ms for the plane, measured). A generated
        URDF is read uncached: the cache would keep every file's text for the life of the client (8 KiB per
        reset) and serve a stale robot when a path is rewritten (measured: 25-38 mm of end-effector error from
        the previous episode's robot)."""
        self.client.setPhysicsEngineParameter(enableFileCaching=int(cache))
        return self.client.loadURDF(path, position, flags=flags)

    def _urdf_dir(self) -> Path:
        """This sim's temporary folder (made on first use, stale ones of dead processes removed then; made again
        if something deleted it)."""
        if self._tmpdir is None:
            remove_stale_urdf_dirs()
            self._tmpdir = tempfile.mkdtemp(prefix=f"{URDF_DIR_PREFIX}{os.getpid()}-")
        os.makedirs(self._tmpdir, exist_ok=True)
        return Path(self._tmpdir)

    def _load_body(self, params: RobotParams) -> None:
        h = params.hash()
        if self.body is not None and self._body_hash == h:
            return
        self._q_arm = None
        if self.body is not None:
            # a fresh world instead of removeBody(): nothing of the old body stays in PyBullet's memory
            self.client.resetSimulation()
            self.body = None
            self._markers, self._marker_shape = [], None
            self._build_world()
        flags = pybullet.URDF_USE_INERTIA_FROM_FILE | pybullet.URDF_MAINTAIN_LINK_ORDER
        at = [0, 0, params.wheel_radius]
        if params == RobotParams.nominal() and urdf.NOMINAL_URDF.exists():
            self.body = self._load_urdf(str(urdf.NOMINAL_URDF), at, cache=True, flags=flags)
        else:
            path = urdf.write_urdf(params, self._urdf_dir() / "robot.urdf")
            try:
                self.body = self._load_urdf(str(path), at, cache=False, flags=flags)
            finally:
                path.unlink(missing_ok=True)
        self._body_hash = h
        if len(self._marker_points) and not self._markers:
            self.draw_path(self._marker_points)
        names = {}
        for j in range(self.client.getNumJoints(self.body)):
            info = self.client.getJointInfo(self.body, j)
            names[info[1].decode()] = j
            names["link:" + info[12].decode()] = j
        self.arm_ids = [names[n] for n in urdf.arm_joints(params.n_joints)]
        self.wheel_ids = [names[n] for n in urdf.WHEEL_JOINTS]
        self.act_ids = self.arm_ids + self.wheel_ids
        self.ee_id = names["link:" + urdf.EE_LINK]
        for n in urdf.CASTER_LINKS:
            self.client.changeDynamics(
                self.body, names["link:" + n], lateralFriction=0.0, rollingFriction=0.0, spinningFriction=0.0
            )
        for w in self.wheel_ids:
            self.client.changeDynamics(self.body, w, lateralFriction=1.5, rollingFriction=0.0, spinningFriction=0.0)
        for j in range(-1, self.client.getNumJoints(self.body)):
            self.client.changeDynamics(self.body, j, linearDamping=0.0, angularDamping=0.0, jointDamping=0.0)
        # free the motors' default velocity motors (they would hold the wheels otherwise)
        self.client.setJointMotorControlArray(
            self.body,
            self.act_ids,
            pybullet.VELOCITY_CONTROL,
            targetVelocities=[0.0] * len(self.act_ids),
            forces=[0.0] * len(self.act_ids),
        )

    def set_state(self, q: np.ndarray, base_pose: np.ndarray) -> None:
        """Put the body at joint angles `q` (n + 2) and platform pose (x, y, yaw) at rest (no PyBullet step)."""
        p = self._params
        self._q_arm = None
        quat = self.client.getQuaternionFromEuler([0.0, 0.0, float(base_pose[2])])
        self.client.resetBasePositionAndOrientation(
            self.body, [float(base_pose[0]), float(base_pose[1]), p.wheel_radius], quat
        )
        self.client.resetBaseVelocity(self.body, [0, 0, 0], [0, 0, 0])
        for j, angle in zip(self.act_ids, q):
            self.client.resetJointState(self.body, j, float(angle), 0.0)

    def reset(self, params: RobotParams, q0: np.ndarray, base_pose: np.ndarray) -> None:
        """Start an episode with the robot `params` at joint angles `q0` (n + 2) and platform pose (3)."""
        self._params = params
        self._n = params.n_joints
        self._has_robot = True
        self.torque_limits = [*params.arm_torque_limit, params.wheel_torque_limit, params.wheel_torque_limit]
        self._lower = np.array(params.joint_lower)
        self._upper = np.array(params.joint_upper)
        self._lower_f, self._upper_f = [float(v) for v in params.joint_lower], [float(v) for v in params.joint_upper]
        self._q = np.asarray(q0, dtype=float).copy()
        self._pose = np.asarray(base_pose, dtype=float).copy()
        self._u = np.zeros(self._n + 2)
        self._yaw = float(base_pose[2])
        self._synced = False
        if self.dynamics == "physics":
            self._load_body(params)
            self.set_state(self._q, self._pose)
            self._synced = True

    def set_params(self, params: RobotParams) -> None:
        """Kinematic mode: change the robot's lengths mid-episode (the env's `wear_rate`); the state is kept and
        the next `state()` is the FK of the new robot. Physics mode cannot: a loaded body's links are fixed."""
        if self.dynamics != "kinematic":
            raise RuntimeError("set_params needs dynamics='kinematic': a loaded PyBullet body's lengths are fixed")
        self._params = params
        self._synced = False

    # --- stepping --------------------------------------------------------------------------------------
    def _limit(self, q_arm: list[float], u: list[float]) -> int:
        """Zero (in place) the arm speeds of `u` that would push a joint past its limit; returns how many.
        Written out in floats: n comparisons, where numpy's per-call overhead would dominate."""
        hits = 0
        for i, (q, lo, hi) in enumerate(zip(q_arm, self._lower_f, self._upper_f)):
            v = u[i]
            if (v > 0.0 and q >= hi) or (v < 0.0 and q <= lo):
                u[i] = 0.0
                hits += 1
        return hits

    def step(self, u: np.ndarray) -> int:
        """Apply the joint/wheel speeds `u` (n + 2, rad/s) for one control step; returns joint-limit hits."""
        if self.dynamics == "kinematic":
            return self._step_kinematic(u)
        return self._step_physics(u)

    def _step_kinematic(self, u: np.ndarray) -> int:
        """`_limit`, the exact integration and the clamp at the limits, in Python floats over the n + 2 entries
        (the same IEEE operations as the array code they replaced, without its ~15 numpy calls on arrays of 8)."""
        n, dt = self._n, self.dt
        uu = u.tolist()
        q = self._q.tolist()
        hits = self._limit(q, uu)
        for i, (lo, hi) in enumerate(zip(self._lower_f, self._upper_f)):
            qi = q[i] + uu[i] * dt
            if qi > hi or qi < lo:
                qi = min(max(qi, lo), hi)  # the joint reached its limit inside the step: it stops there
                uu[i] = 0.0
                hits += 1
            q[i] = qi
        q[n] = q[n] + uu[n] * dt
        q[n + 1] = q[n + 1] + uu[n + 1] * dt
        self._pose = K.integrate_unicycle(self._params, self._pose, uu[n:], dt)
        self._q = np.array(q)
        self._u = np.array(uu)
        self._synced = False
        return hits

    def _step_physics(self, u: np.ndarray) -> int:
        targets = u.tolist()
        q_arm = self._q_arm  # the last read's, if nothing has moved the body since
        if q_arm is None:
            q_arm = [s[0] for s in pybullet.getJointStates(self.body, self.arm_ids, self.client_id)]
        self._q_arm = None
        hits = self._limit(q_arm, targets)
        self._motor_array(
            self.body, self.act_ids, pybullet.VELOCITY_CONTROL, targetVelocities=targets, forces=self.torque_limits
        )
        step, cid = pybullet.stepSimulation, self.client_id
        for _ in range(self.n_substeps):
            step(cid)
        return hits

    # --- state -----------------------------------------------------------------------------------------
    def state(self) -> RobotState:
        """The noise-free state as arrays (from the same read as `readings`)."""
        values, xy, roll_pitch = self._read()
        m = self._n + 2
        return RobotState(
            ee_pos=np.array(values[0:3]),
            ee_vel=np.array(values[3:6]),
            arm_base_pos=np.array(values[6:8]),
            arm_base_vel=np.array(values[8:10]),
            base_pose=np.array([xy[0], xy[1], values[10]]),
            joint_pos=np.array(values[11 : 11 + m]),
            joint_vel=np.array(values[11 + m :]),
            roll_pitch=roll_pitch,
        )

    def readings(self) -> tuple[list[float], tuple[float, float]]:
        """What `state()` holds for the sensors, as floats in `sensors.SENSOR_KEYS` order (ee_pos, ee_vel,
        arm_base_pos, arm_base_vel, base yaw, joint_pos, joint_vel: 11 + 2 (n + 2) values), and the platform's
        (roll, pitch): the env's per-step read (no arrays are built for it)."""
        values, _, roll_pitch = self._read()
        return values, roll_pitch

    def _read(self) -> tuple[list[float], tuple[float, float], tuple[float, float]]:
        """One read of the robot, in floats: (the `readings` values, x and y of P_0, (roll, pitch))."""
        if self.dynamics == "physics":
            return self._read_physics()
        # kinematic: the FK of the integrated state; the velocities are the BLAS products J u
        p, q, pose, u = self._params, self._q, self._pose, self._u
        ee_pos, J, J_pc, pc = K.ee_jacobian_and_arm_base(p, q[: self._n], pose)
        x, y, yaw = pose.tolist()
        values = [*ee_pos, *(J @ u).tolist(), *pc, *(J_pc @ u).tolist(), yaw]
        return values + q.tolist() + u.tolist(), (x, y), (0.0, 0.0)

    def _read_physics(self) -> tuple[list[float], tuple[float, float], tuple[float, float]]:
        """One read of the PyBullet body, in floats: (the `readings` values, x and y of P_0, (roll, pitch))."""
        body, cid, pb = self.body, self.client_id, pybullet
        js = pb.getJointStates(body, self.act_ids, cid)
        ls = pb.getLinkState(body, self.ee_id, 1, 1, cid)  # with the link velocity, forward kinematics updated
        pos, orn = pb.getBasePositionAndOrientation(body, cid)
        lin, ang = pb.getBaseVelocity(body, cid)
        roll, pitch, yaw_wrapped = pb.getEulerFromQuaternion(orn, cid)
        # continuous yaw: the wrapped angle's nearest representative to the last one
        self._yaw += (yaw_wrapped - self._yaw + math.pi) % (2 * math.pi) - math.pi
        yaw = self._yaw
        d, w = self._params.mount_offset, ang[2]
        cy, sy = math.cos(yaw), math.sin(yaw)
        x, y = pos[0], pos[1]
        values = [*ls[0], *ls[6], x + d * cy, y + d * sy, lin[0] - d * w * sy, lin[1] + d * w * cy, yaw]
        q = [s[0] for s in js]
        self._q_arm = q[: self._n]
        values += q
        values += [s[1] for s in js]
        return values, (x, y), (roll, pitch)

    # --- rendering -------------------------------------------------------------------------------------
    def sync_bodies(self) -> None:
        """Kinematic mode: put the PyBullet body where the integrated state is (only needed to render)."""
        if self.dynamics == "kinematic" and not self._synced and self._has_robot:
            self._load_body(self._params)
            self.set_state(self._q, self._pose)
            self._synced = True

    def draw_path(self, points: np.ndarray) -> None:
        """Show the desired path as small visual-only spheres (debug lines do not show headless); kept across
        a rebuilt world. One visual shape per world, shared by all markers."""
        for m in self._markers:
            self.client.removeBody(m)
        self._markers = []
        self._marker_points = np.array(points, dtype=float).reshape(-1, 3)
        if len(points) == 0:
            return
        if self._marker_shape is None:
            self._marker_shape = self.client.createVisualShape(
                pybullet.GEOM_SPHERE, radius=0.012, rgbaColor=[0.1, 0.8, 0.2, 1]
            )
        shape = self._marker_shape
        for pt in points:
            self._markers.append(
                self.client.createMultiBody(baseMass=0, baseVisualShapeIndex=shape, basePosition=[float(v) for v in pt])
            )

    def render(self, target: np.ndarray, distance: float = 2.6, width: int = 480, height: int = 360) -> np.ndarray:
        """An RGB image (height, width, 3) uint8 from TinyRenderer, looking at `target` from `distance` m."""
        self.sync_bodies()
        c = self.client
        view = c.computeViewMatrixFromYawPitchRoll(
            cameraTargetPosition=[float(v) for v in target],
            distance=distance,
            yaw=40.0,
            pitch=-20.0,
            roll=0.0,
            upAxisIndex=2,
        )
        proj = c.computeProjectionMatrixFOV(fov=50.0, aspect=width / height, nearVal=0.05, farVal=20.0)
        img = c.getCameraImage(width, height, view, proj, renderer=pybullet.ER_TINY_RENDERER)
        rgba = np.reshape(np.asarray(img[2], dtype=np.uint8), (height, width, 4))
        return rgba[:, :, :3].copy()

    # --- teardown --------------------------------------------------------------------------------------
    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        try:
            if pybullet.isConnected(physicsClientId=self.client_id):
                self.client.disconnect()
        finally:
            if self._tmpdir is not None:
                shutil.rmtree(self._tmpdir, ignore_errors=True)
                self._tmpdir = None

    def __del__(self):
        with contextlib.suppress(Exception):
            self.close()
