"""The PyBullet world behind one env: one client, the robot body, the motors and the readings.

* Physics mode (`WheeledPumaEnv(dynamics="physics")`): velocity-controlled motors with torque limits
  (`RobotParams.*_torque_limit`); the platform moves by wheel contact and friction, the casters are frictionless.
  One control step = `n_substeps` PyBullet steps (`command`). `read` copies the raw state (joint angles and speeds,
  base position, orientation and velocity) into the engine's `io` row; the end-effector, p_c and everything else
  the sensors report are computed from it by `mobman_env.engine.physics`, the same chain as kinematic mode.
* Kinematic mode makes no PyBullet call per step (the engine integrates the state); a `Sim` exists there only to
  render, and `show` puts the body where the engine's state is.

Every PyBullet call goes to this sim's own client (`self.client`, or pybullet's functions with its `client_id`,
bound once); `close()` is safe to call twice.

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
import os
import re
import shutil
import sys
import tempfile
from contextlib import contextmanager
from pathlib import Path

import numpy as np

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


def display_available() -> bool:
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


class Sim:
    """One PyBullet client and the robot in it (see the module docstring)."""

    def __init__(self, dt: float, n_substeps: int, gui: bool = False):
        if gui and not display_available():
            raise RuntimeError(
                "render_mode='human' needs a display (DISPLAY is not set) and PyBullet's GUI would kill the "
                "process without one; use render_mode='rgb_array' for headless rendering"
            )
        self.dt = float(dt)
        self.n_substeps = int(n_substeps)
        self.gui = bool(gui)
        self._tmpdir: str | None = None
        self._closed = False
        with _quiet_stdout():
            self.client = bullet_client.BulletClient(connection_mode=pybullet.GUI if gui else pybullet.DIRECT)
        self.client_id = self.client._client
        # the per-step calls skip BulletClient.__getattr__, which builds a new partial per call (0.7 us each,
        # measured): the motor command is the client's partial, bound once; the reads and stepSimulation are
        # pybullet's functions called with this client's id as a positional argument
        self._motor_array = self.client.setJointMotorControlArray
        self.client.setAdditionalSearchPath(pybullet_data.getDataPath())
        self.body: int | None = None
        self._body_hash: str | None = None
        self._markers: list[int] = []
        self._marker_points = np.empty((0, 3))
        self._marker_shape: int | None = None
        self._params = RobotParams.nominal()  # replaced by reset(); no body exists before it
        #: torque limits of the n + 2 actuators (n arm joints, left, right wheel), N m (set by reset)
        self.torque_limits: list[float] = []
        self._build_world()

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
        quat = self.client.getQuaternionFromEuler([0.0, 0.0, float(base_pose[2])])
        self.client.resetBasePositionAndOrientation(
            self.body, [float(base_pose[0]), float(base_pose[1]), p.wheel_radius], quat
        )
        self.client.resetBaseVelocity(self.body, [0, 0, 0], [0, 0, 0])
        for j, angle in zip(self.act_ids, q):
            self.client.resetJointState(self.body, j, float(angle), 0.0)

    def reset(self, params: RobotParams, q0: np.ndarray, base_pose: np.ndarray) -> None:
        """Put the robot `params` (its body loaded if it changed) at joint angles `q0` (n + 2) and platform pose
        (x, y, yaw of P_0), at rest."""
        self._params = params
        self.torque_limits = [*params.arm_torque_limit, params.wheel_torque_limit, params.wheel_torque_limit]
        self._load_body(params)
        self.set_state(q0, base_pose)

    show = reset  # kinematic mode: put the body where the engine's state is (only to render)

    # --- stepping --------------------------------------------------------------------------------------
    def command(self, targets: list[float]) -> None:
        """One control step: the motors' target speeds (n + 2, rad/s) under their torque limits, then
        `n_substeps` PyBullet steps."""
        self._motor_array(
            self.body, self.act_ids, pybullet.VELOCITY_CONTROL, targetVelocities=targets, forces=self.torque_limits
        )
        step, cid = pybullet.stepSimulation, self.client_id
        for _ in range(self.n_substeps):
            step(cid)

    def read(self) -> tuple[float, ...]:
        """The raw state, in the order of the engine's `io_columns` fields `phys_q` to `phys_ang_vel`: the n + 2
        joint angles, their speeds, the base's position (P_0 at wheel-axle height), orientation quaternion (x, y,
        z, w), linear and angular velocity."""
        body, cid, pb = self.body, self.client_id, pybullet
        q, qd, _, _ = zip(*pb.getJointStates(body, self.act_ids, cid))
        pos, orn = pb.getBasePositionAndOrientation(body, cid)
        lin, ang = pb.getBaseVelocity(body, cid)
        return q + qd + pos + orn + lin + ang

    # --- rendering -------------------------------------------------------------------------------------
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

    def render(
        self,
        target: np.ndarray,
        distance: float = 2.6,
        width: int = 480,
        height: int = 360,
        yaw: float = 40.0,
        pitch: float = -20.0,
    ) -> np.ndarray:
        """An RGB image (height, width, 3) uint8 from TinyRenderer, looking at `target` from `distance` m, the
        camera `yaw` degrees about the vertical and `pitch` degrees above the horizon (negative: from above)."""
        c = self.client
        view = c.computeViewMatrixFromYawPitchRoll(
            cameraTargetPosition=[float(v) for v in target],
            distance=distance,
            yaw=yaw,
            pitch=pitch,
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
