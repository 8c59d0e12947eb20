"""mobman_env.robots: arm descriptions (PUMA 560, UR5, Panda, random arms) and their generic kinematics.

One `ArmDescription` per arm (DH convention and table, joint/speed/torque limits, masses, centres of mass,
inertias, tool, mount) is the single source from which the kinematics, the URDF and the spaces are to be
derived (issue 13, DESIGN.md "Release 0.2": Robots). `mobman_env.params.RobotParams` joins one description and
the platform; the env, the sim, the URDF writer and the controllers derive everything from it (`sources` says
which robot an env has).

| module | what |
|---|---|
| `description` | `ArmDescription` (validated, frozen), `rod_inertia`, `standard_segment` |
| `kinematics` | FK of the tool point and the analytic 3 x n position Jacobian, any n, both conventions, single or batched |
| `catalogue` | `PUMA560` (today's `RobotParams`, number for number), `UR5`, `PANDA`, `ROBOTS` |
| `random_arms` | `random_arm(rng, accept=None)`: the random 6-joint family, its start rule and acceptance rate |
| `starts` | `STARTS` (q0 and heading per named arm) and the kinematic checks behind them |
| `arm_urdf` | `arm_urdf_string(arm)`: the arm alone as URDF, the design note's frame mapping, checked in PyBullet |
| `bench` | timing of the kinematics against numpy 4 x 4 products |
| `sources` | `robot_source(name)`: the env's robot (fixed catalogue arm or a random arm per reset) and its start |
| `__main__` | `python -m mobman_env.robots {table,select,acceptance,ceiling,bench}`: the quoted figures, regenerated |

## Design note for the integration (done in issue 13's second session; kept as the record of the mapping)

**URDF** (`mobman_env.urdf.urdf_string` to take an `ArmDescription`; all arm joints revolute, `<axis xyz="0 0
1"/>`, one link per joint named `link1..linkn`, joints `joint1..jointn`, the mount frame = DH frame 0 at
(`mount_offset`, 0, `base_height` - wheel radius) in `base_link`):

* standard DH: URDF applies a fixed origin first, then turns about z, while A_i = Rz(theta) Tz(d) Tx(a)
  Rx(alpha) turns first. So joint i's origin is the fixed part Tz(d_{i-1}) Tx(a_{i-1}) Rx(alpha_{i-1}) of the
  previous row (identity for joint 1), and link i's URDF frame is DH frame i-1 turned by theta_i, not DH frame
  i: a centre of mass c and inertia I given in DH frame i go into link i's `<inertial>` as
  xyz = (a_i, 0, d_i) + Rx(alpha_i) c and rpy = (alpha_i, 0, 0) (the inertia keeps its DH-frame-i axes) —
  what today's `urdf_string` does for the PUMA. The `ee` link is fixed to link n at (a_n, 0, d_n) +
  Rx(alpha_n) (0, 0, tool). `theta_offset`: see below.
* modified DH: A_i = Rx(alpha_i) Tx(a_i) Rz(theta_i) Tz(d_i) = [Rx(alpha_i) Tx(a_i) Tz(d_i)] Rz(theta_i)
  (Rz and Tz commute), which is URDF's order: joint i's origin is xyz = (a_i, -d_i sin alpha_i, d_i cos
  alpha_i), rpy = (alpha_i, 0, 0) from link i-1's frame, and link i's URDF frame *is* DH frame i, so centres of
  mass and inertias go in unchanged. The `ee` link sits at (0, 0, tool) in link n.
* `theta_offset` (both conventions): Rz(offset_i) commutes with joint i's Rz(q_i), so right-multiply joint i's
  origin by Rz(offset_i) (convert the composed rotation to rpy); `joint_pos` stays q.
* `<limit>` from `joint_lower`/`joint_upper`/`speed_limit`/`torque_limit`; inertias as full tensors
  (ixx, iyy, izz, ixy, ixz, iyz are all set: the Panda's have products of inertia).
* `arm_urdf.arm_urdf_string` implements exactly this for the arm alone; `tests/test_robots.py` loads it in
  PyBullet and finds the `ee` frame at `kinematics.arm_point` (max error < 1e-6 m, z axis = z_n) at 50 random
  configurations for the PUMA, the UR5, the Panda, three random arms and the UR5 and Panda with non-zero
  theta offsets. The integrated writer can call it for the arm and keep the platform parts of `mobman_env.urdf`.

**Spaces and facts** (n = `arm.n_joints`, n_act = `arm.n_actuators` = n + 2): action `Box(-1, 1, (n_act,))`
= [arm speeds, left wheel, right wheel]; `action_scale` = [*`speed_limit`, wheel, wheel]; `joint_pos` and
`joint_vel` `Box(.., (n_act,))`; `arm_joint_pos` accepts n or n + 2 numbers and is checked against the
description's limits; `EnvFacts` gains `n_actuators` (today it carries `action_scale`, whose length is already
the count: `n_actuators = len(action_scale)` keeps old pickles/configs meaningful). `nominal_params.tool` is
`ArmDescription.tool`; `model_error` perturbs `ArmDescription.length_slots` (every non-zero `a` in row order,
every non-zero `d`, then `tool`) through `scaled_lengths`, then the platform's r, b and mount offset: for the
PUMA that is a2, a3, d3, d4, tool, r, b, d, today's `PERTURBED_FIELDS` in today's order, and a test shows the
same normals give the same bits as `RobotParams.perturbed` (still check `mobman-eval paper` before and after).

**Kinematics**: `robots.kinematics` (one arm) and `mobman_env.kinematics` (the arm on its platform) are the
Python faces of `mobman_env.engine`, the one implementation of the chain (release 0.3); `link_frames` (dense
4 x 4 products) is the independent reference the tests check it against.

**What was PUMA-specific** (all of it is generic now; everything that assumes 6 arm joints or 8 actuators; `git grep` of 6, 8,
`range(6)`, `[:6]`, `[6:]`, shapes, 2026-12-01):

* `mobman_env/kinematics.py`: module constants `N_ARM = 6`, `N_ACT = 8`; `dh_transforms`, `dh_frames`
  (7 frames), `arm_point_and_jacobian` (`frames[:6]`), `_paper_parts` and `arm_base_jacobian` ((3, 8), (2, 8),
  `[:, N_ARM:]`), `ee_position` (docstring: 6 angles); `RobotParams` is the PUMA (a2, a3, d3, d4 fields).
* `mobman_env/params.py`: `RobotParams` (PUMA fields a2/a3/d3/d4, `dh_a`/`dh_d`/`dh_alpha` 6-long,
  `PERTURBED_FIELDS` names PUMA lengths, `action_scale` "8 actuators").
* `mobman_env/urdf.py`: `ARM_JOINTS = joint1..joint6` (module), `urdf_string` (`range(6)`, `i == 5` carries the
  tool, `link6` in the `ee` joint, robot name "wheeled_puma560"), `NOMINAL_URDF` (one shipped file).
* `mobman_env/sim.py`: `RobotState` ((8,) joint_pos/joint_vel), `Sim.__init__` (`np.zeros(8)` twice),
  `Sim._load_body` (`[0.0] * 8` motor targets), `Sim.reset` (`np.zeros(8)`), `Sim._limit` (`u[:6]`),
  `Sim._step_kinematic` (`q[:6]`, `u[:6]`, `u[6:]` wheels), `Sim._state_kinematic` (`q[:6]`; since merged into `Sim._read`).
* `mobman_env/env.py`: `PAPER_ARM_JOINT_POS` (6 angles, PUMA), `WheeledPumaEnv.__init__` (`Box(.., (8,))`,
  `RobotParams.nominal()`), `_joint_vector` (shapes (6,)/(8,), `arr[:6]`, PUMA limits from
  `RobotParams.nominal()`), `_make_observation_space` (`box(8, ..)` for joint_pos/joint_vel), `step` (shape
  (8,) check and message), the class docstring's action table.
* `mobman_env/__init__.py`: `TASKS`/`register_envs` (only `WheeledPuma-*` ids, one entry point).
* `policies/laws/nnbc_plus.py`: module `N_ACT = 8`, `N_STATE`, `N_PROBE`; `NNBCPlus.__init__` (refuses
  `len(action_scale) != 8`), `J_hat`, `Jdot_hat`, `_reset` (`q[:6]` posture), `_measure`, `_finish_probe`,
  `_kalman`, `_act` (all `N_ACT`): the model-free law itself is generic; only the constant must come from
  `EnvFacts`.
* `policies/laws/jmpi.py`: `_ModelPolicy._command` (`joint_pos[:6]`, `RobotParams` kinematics), `JMPI`/`Oracle`
  docstrings and errors name `RobotParams`.
* `policies/laws/nnbc.py`: `NNBC._initial_jacobian` (`joint_pos[:6]`, PUMA kinematics for `j0="nominal"`).
* `eval/rollout.py`: `rollout` (`np.empty((n, 8))` actions buffer, `a.shape == (1, 8)` batch-of-one check).
* `eval/metrics.py`: `peak_speeds(..., n_arm=6)` default.
* `eval/speed.py`: `env_vs_bare` (random actions of shape (steps, 8)).
* `train/evaluation.py`: `ZeroPolicy.predict` (`np.zeros(8)`).
* `policies/laws/simple.py` and `policies/base.py` already size everything from `len(action_scale)`: generic.

May import: numpy, the standard library, `mobman_env.validation`, `mobman_env.paths` and `mobman_env.params`
(in `starts` and `sources` only: the task paths, the platform's wheel numbers, `RobotParams`; `params` imports
`description` and `catalogue`, so this package's `__init__` does not import `starts` or `sources`). Nothing
here imports the env, the sim, PyBullet or the controllers.
"""

from __future__ import annotations

from mobman_env.robots.catalogue import PANDA, PUMA560, ROBOTS, UR5
from mobman_env.robots.description import CONVENTIONS, ArmDescription
from mobman_env.robots.kinematics import arm_point, arm_point_and_jacobian, arm_point_and_jacobian_batch, link_frames
from mobman_env.robots.random_arms import RandomArm, random_arm

__all__ = [
    "CONVENTIONS",
    "PANDA",
    "PUMA560",
    "ROBOTS",
    "UR5",
    "ArmDescription",
    "RandomArm",
    "arm_point",
    "arm_point_and_jacobian",
    "arm_point_and_jacobian_batch",
    "link_frames",
    "random_arm",
]
