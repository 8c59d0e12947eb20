"""mobman_env.robots: arm descriptions, generic kinematics, random arms and the named arms' starts.

Known answers are computed here independently: the UR5's and the Panda's zero-configuration flange from their
DH tables by hand, and a plain 4 x 4 product of the textbook DH matrices written again below.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from mobman_env import kinematics as K
from mobman_env.params import RobotParams
from mobman_env.robots import random_arms as RA
from mobman_env.robots import starts as S
from mobman_env.robots.catalogue import PANDA, PUMA560, ROBOTS, UR5
from mobman_env.robots.description import ArmDescription, rod_inertia
from mobman_env.robots.kinematics import (
    arm_point,
    arm_point_and_jacobian,
    arm_point_and_jacobian_batch,
    link_frames,
)

RANDOM_ARMS = [RA.random_arm(np.random.default_rng(s)).arm for s in range(3)]
ARMS = [PUMA560, UR5, PANDA, *RANDOM_ARMS]
ARM_IDS = [a.name if i < 3 else f"{a.name}-seed{i - 3}" for i, a in enumerate(ARMS)]


def _rz(t):
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def _rx(t):
    c, s = math.cos(t), math.sin(t)
    return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1.0]])


def _tz(x):
    T = np.eye(4)
    T[2, 3] = x
    return T


def _tx(x):
    T = np.eye(4)
    T[0, 3] = x
    return T


def reference_point(arm: ArmDescription, q) -> np.ndarray:
    """The tool point by elementary 4 x 4 matrices, one convention at a time (independent of the library)."""
    T = np.eye(4)
    for i in range(arm.n_joints):
        th = q[i] + arm.theta_offset[i]
        if arm.convention == "standard":
            T = T @ _rz(th) @ _tz(arm.d[i]) @ _tx(arm.a[i]) @ _rx(arm.alpha[i])
        else:
            T = T @ _rx(arm.alpha[i]) @ _tx(arm.a[i]) @ _rz(th) @ _tz(arm.d[i])
    return (T @ _tz(arm.tool))[:3, 3]


def _configs(arm: ArmDescription, n: int, seed: int) -> np.ndarray:
    lo, hi = arm.limits
    return np.random.default_rng(seed).uniform(np.maximum(lo, -math.pi), np.minimum(hi, math.pi), (n, arm.n_joints))


# --- the PUMA: today's numbers, today's kinematics ---------------------------------------------------------
def test_puma_description_is_release_01s_robot():
    """`RobotParams()` is the PUMA description on the platform, and its digest (a function of every number)
    and a worn copy's are release 0.1's (computed with release 0.1's `RobotParams`, commit e52e574)."""
    p = RobotParams.nominal()
    assert p.arm is PUMA560 and PUMA560.convention == "standard" and PUMA560.theta_offset == (0.0,) * 6
    assert p.n_actuators == len(p.action_scale) == 8
    assert p.hash() == "36aafecb4b8c9eb8"
    assert p.perturbed(np.random.default_rng(10000), 0.05).hash() == "d30348a248dc3a5c"
    assert p.perturbed(np.random.default_rng(7), 0.05).a2.hex() == "0x1.ba30bdd1fc525p-2"
    assert (p.a2, p.a3, p.d3, p.d4, p.tool) == (0.4318, 0.0203, 0.15005, 0.4318, 0.2)
    with pytest.raises(AttributeError, match="no DH length 'a7'"):
        p.a7  # noqa: B018


def test_puma_generic_kinematics_equal_todays():
    p = RobotParams.nominal()
    for q in _configs(PUMA560, 50, seed=1):
        r0, J0 = K.arm_point_and_jacobian(p, q)
        r1, J1 = arm_point_and_jacobian(PUMA560, q)
        np.testing.assert_allclose(r1, r0, rtol=0, atol=1e-12)
        np.testing.assert_allclose(J1, J0, rtol=0, atol=1e-12)


def test_puma_worn_copy_equals_robot_params_perturbed_bit_for_bit():
    """The integration can keep the PUMA's draws: the same normals, applied through `length_slots`, give the
    same bits as `RobotParams.perturbed` (which draws a2, a3, d3, d4, tool, r, b, d in one call)."""
    from mobman_env.params import PERTURBED_FIELDS

    nominal = RobotParams.nominal()
    assert [f"{n}{i + 1}" if n != "tool" else n for n, i in PUMA560.length_slots] == list(PERTURBED_FIELDS[:5])
    for seed in range(5):
        worn = nominal.perturbed(np.random.default_rng(seed), 0.05)
        z = np.clip(np.random.default_rng(seed).standard_normal(len(PERTURBED_FIELDS)), -3.0, 3.0)
        arm = PUMA560.scaled_lengths(1.0 + 0.05 * z[: len(PUMA560.length_slots)])
        assert arm.a == tuple(worn.dh_a) and arm.d == tuple(worn.dh_d) and arm.tool == worn.tool
        assert arm.masses == PUMA560.masses and arm.joint_lower == PUMA560.joint_lower
    with pytest.raises(ValueError, match="5 perturbable lengths"):
        PUMA560.scaled_lengths([1.0, 1.0])
    assert len(UR5.length_slots) == 7 and len(PANDA.length_slots) == 8


# --- every arm ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("arm", ARMS, ids=ARM_IDS)
def test_jacobian_matches_central_differences(arm):
    h = 1e-6
    for q in _configs(arm, 10, seed=2):
        J = arm_point_and_jacobian(arm, q)[1]
        assert J.shape == (3, arm.n_joints)
        fd = np.array([(arm_point(arm, q + h * e) - arm_point(arm, q - h * e)) / (2 * h) for e in np.eye(arm.n_joints)])
        np.testing.assert_allclose(J, fd.T, rtol=0, atol=1e-6)


@pytest.mark.parametrize("arm", ARMS, ids=ARM_IDS)
def test_point_equals_a_plain_matrix_product(arm):
    for q in _configs(arm, 5, seed=3):
        np.testing.assert_allclose(arm_point(arm, q), reference_point(arm, q), rtol=0, atol=1e-12)
        F = link_frames(arm, q)
        np.testing.assert_allclose(F[-1, :3, 3] + arm.tool * F[-1, :3, 2], reference_point(arm, q), atol=1e-12)


@pytest.mark.parametrize("arm", ARMS, ids=ARM_IDS)
def test_batch_equals_single(arm):
    Q = _configs(arm, 7, seed=4)
    P, J = arm_point_and_jacobian_batch(arm, Q)
    assert P.shape == (7, 3) and J.shape == (7, 3, arm.n_joints)
    for i, q in enumerate(Q):
        r, Ji = arm_point_and_jacobian(arm, q)
        np.testing.assert_allclose(P[i], r, rtol=0, atol=1e-15)
        np.testing.assert_allclose(J[i], Ji, rtol=0, atol=1e-15)


def test_ur5_and_panda_zero_configuration_by_hand():
    # UR5, standard DH, q = 0: x1 = x0, z1 = -y0 (alpha1 = pi/2); a2, a3 along -x; d4 along -y; d5 along -z
    # (z4 = -z0); d6 along -y (z5 = -y0), the tool too
    flange = np.array([-0.425 - 0.39225, -0.10915 - 0.0823, 0.089459 - 0.09465])
    np.testing.assert_allclose(arm_point(UR5.replace(tool=0.0), np.zeros(6)), flange, atol=1e-12)
    np.testing.assert_allclose(arm_point(UR5, np.zeros(6)), flange + [0, -UR5.tool, 0], atol=1e-12)
    # Panda, modified DH, q = 0: up d1 + d3 + d5 = 1.033 m; a4 and a5 cancel; a7 = 0.088 along x; z7 points
    # down, so the 0.107 m flange and the 0.103 m hand go down
    np.testing.assert_allclose(arm_point(PANDA.replace(tool=0.0), np.zeros(7)), [0.088, 0, 1.033 - 0.107], atol=1e-12)
    np.testing.assert_allclose(arm_point(PANDA, np.zeros(7)), [0.088, 0, 1.033 - 0.107 - 0.103], atol=1e-12)


def test_modified_and_standard_conventions_agree_on_the_same_arm():
    """Craig's table of a standard-DH arm whose last row has a = alpha = 0: row i's a, alpha move to row i + 1.
    Both conventions must give the same point and Jacobian; swapping the label alone must not."""
    for arm in (PUMA560, UR5):
        craig = arm.replace(convention="modified", a=(0.0, *arm.a[:-1]), alpha=(0.0, *arm.alpha[:-1]))
        for q in _configs(arm, 10, seed=5):
            r0, J0 = arm_point_and_jacobian(arm, q)
            r1, J1 = arm_point_and_jacobian(craig, q)
            np.testing.assert_allclose(r1, r0, atol=1e-12)
            np.testing.assert_allclose(J1, J0, atol=1e-12)
        relabelled = arm.replace(convention="modified")
        assert np.linalg.norm(arm_point(relabelled, q) - arm_point(arm, q)) > 1e-3


def test_too_few_angles_are_refused():
    with pytest.raises(ValueError, match="panda has 7 joints; q must have at least 7 angles"):
        arm_point(PANDA, np.zeros(6))
    with pytest.raises(ValueError, match=r"q must have shape \(N, 7\)"):
        arm_point_and_jacobian_batch(PANDA, np.zeros((3, 6)))
    # extra entries (the wheel angles of joint_pos) are ignored
    np.testing.assert_array_equal(arm_point(UR5, np.r_[np.zeros(6), 5.0, 6.0]), arm_point(UR5, np.zeros(6)))


def test_theta_offset_shifts_the_joint_zero():
    off = (0.1, -0.2, 0.3, 0.0, 0.5, -0.6)
    shifted = UR5.replace(theta_offset=off)
    q = _configs(UR5, 1, seed=6)[0]
    np.testing.assert_allclose(arm_point(shifted, q), arm_point(UR5, q + np.array(off)), atol=1e-12)


OFFSET_ARMS = [
    UR5.replace(theta_offset=(0.1, -0.2, 0.3, 0.0, 0.5, -0.6)),
    PANDA.replace(theta_offset=(0.1, -0.2, 0.3, 0.4, 0.5, -0.6, 0.7)),
]


@pytest.fixture
def loaded(request, tmp_path):
    """(arm, client, body, joint indices, ee link index) for the arm `request.param`, loaded from its arm URDF in
    a PyBullet client of its own, disconnected afterwards."""
    import pybullet
    from pybullet_utils.bullet_client import BulletClient

    from mobman_env.robots.arm_urdf import EE_LINK, arm_urdf_string

    arm = request.param
    path = tmp_path / f"{arm.name}.urdf"
    path.write_text(arm_urdf_string(arm))
    client = BulletClient(connection_mode=pybullet.DIRECT)
    try:
        body = client.loadURDF(str(path), useFixedBase=True, flags=pybullet.URDF_USE_INERTIA_FROM_FILE)
        info = [client.getJointInfo(body, j) for j in range(client.getNumJoints(body))]
        joints = [
            next(k for k, row in enumerate(info) if row[1].decode() == f"joint{i + 1}") for i in range(arm.n_joints)
        ]
        ee = next(k for k, row in enumerate(info) if row[12].decode() == EE_LINK)
        yield arm, client, body, joints, ee
    finally:
        client.disconnect()


@pytest.mark.parametrize("loaded", [*ARMS, *OFFSET_ARMS], ids=[*ARM_IDS, "ur5-offsets", "panda-offsets"], indirect=True)
def test_urdf_end_effector_equals_the_numpy_fk(loaded):
    """The design note's frame mapping, checked in PyBullet: the `ee` frame origin is the numpy tool point and
    its z axis is z_n, at 50 random configurations; masses and inertias arrive, the `ee` link is massless."""
    arm, client, body, joints, ee = loaded
    worst = 0.0
    for q in _configs(arm, 50, seed=7):
        for j, v in zip(joints, q):
            client.resetJointState(body, j, float(v))
        state = client.getLinkState(body, ee, computeForwardKinematics=True)
        worst = max(worst, float(np.abs(np.array(state[4]) - arm_point(arm, q)).max()))
        z = np.array(client.getMatrixFromQuaternion(state[5])).reshape(3, 3)[:, 2]
        np.testing.assert_allclose(z, link_frames(arm, q)[-1, :3, 2], atol=1e-6)
    assert worst < 1e-6  # measured: 3e-8 to 6e-8 m
    for i, j in enumerate(joints):
        info = client.getDynamicsInfo(body, j)
        assert info[0] == pytest.approx(arm.masses[i])
        assert sum(info[2]) == pytest.approx(float(np.trace(arm.inertia_matrix(i))), rel=1e-6)
    assert client.getDynamicsInfo(body, ee)[0] == 0.0


@pytest.mark.parametrize("loaded", ARMS, ids=ARM_IDS, indirect=True)
def test_torque_limits_hold_the_arm_against_gravity(loaded):
    """Static gravity torques (PyBullet inverse dynamics, fixed base) at 100 random configurations: below 60% of
    the torque limits for every arm, and below 1/3 for random arms (their limits are 3x a bound on the load)."""
    arm, client, body, joints, ee = loaded
    client.setGravity(0, 0, -9.81)
    n = arm.n_joints
    worst = max(
        float(
            np.max(np.abs(client.calculateInverseDynamics(body, q.tolist(), [0.0] * n, [0.0] * n)) / arm.torque_limit)
        )
        for q in _configs(arm, 100, seed=8)
    )
    assert worst < (1 / 3 + 1e-9 if arm.name.startswith("random") else 0.6)


# --- descriptions refuse what cannot work ------------------------------------------------------------
@pytest.mark.parametrize(
    ("changes", "match"),
    [
        ({"convention": "craig"}, "convention must be one of"),
        ({"a": (0.0,) * 5}, r"lengths differ: \{'a': 5, 'alpha': 6"),
        ({"joint_lower": (0.0,) * 6, "joint_upper": (0.0,) * 6}, "lower < upper"),
        ({"speed_limit": (3.0, 3.0, 0.0, 5.0, 5.0, 5.0)}, r"speed_limit\[2\] must be a finite number > 0"),
        ({"tool": -0.1}, "tool must be a finite number >= 0"),
        ({"masses": (5.0, True, 4.8, 0.82, 0.34, 0.09)}, r"masses\[1\]"),
        # the PUMA's published link-3 inertia breaks the triangle inequality (RobotParams raises Izz for that)
        (
            {
                "inertias": (
                    PUMA560.inertias[0],
                    PUMA560.inertias[1],
                    (0.066, 0.086, 0.0125, 0, 0, 0),
                    *PUMA560.inertias[3:],
                )
            },
            "triangle",
        ),
    ],
)
def test_bad_descriptions_are_refused(changes, match):
    with pytest.raises(ValueError, match=match):
        PUMA560.replace(**changes)


def test_rod_inertia_known_answer():
    m, r, L = 2.0, 0.05, 0.4
    ixx, iyy, izz, ixy, ixz, iyz = rod_inertia(m, r, L, (1.0, 0.0, 0.0))
    assert ixx == pytest.approx(0.5 * m * r * r) and iyy == izz == pytest.approx(m * (3 * r * r + L * L) / 12)
    assert ixy == ixz == iyz == 0.0
    t = rod_inertia(m, r, L, (1.0, 1.0, 0.0))  # the same rod turned 45 deg: same trace, a product term
    assert sum(t[:3]) == pytest.approx(ixx + iyy + izz) and t[3] != 0.0


@pytest.mark.parametrize("arm", [PUMA560, UR5, PANDA], ids=["puma560", "ur5", "panda"])
def test_last_joint_turns_about_the_tool_axis_and_the_wrist_moves_the_point(arm):
    for q in _configs(arm, 10, seed=9):
        J = arm_point_and_jacobian(arm, q)[1]
        assert np.abs(J[:, -1]).max() < 1e-15
        assert np.linalg.norm(J[:, -2]) > 0.05  # the joint before it moves the point (the tool's purpose)


def test_named_arms():
    assert set(ROBOTS) == {"puma560", "ur5", "panda"}
    assert (UR5.n_joints, UR5.n_actuators, UR5.convention) == (6, 8, "standard")
    assert (PANDA.n_joints, PANDA.n_actuators, PANDA.convention) == (7, 9, "modified")
    assert PANDA.tool == 0.103 and PANDA.d[-1] == 0.107


# --- random arms ---------------------------------------------------------------------------------------
def test_random_arm_is_deterministic_per_seed_and_differs_across_seeds():
    a = RA.random_arm(np.random.default_rng(11))
    b = RA.random_arm(np.random.default_rng(11))
    c = RA.random_arm(np.random.default_rng(12))
    assert a == b
    assert a.arm.a != c.arm.a


@pytest.mark.parametrize("seed", range(20))
def test_random_arm_is_valid_and_its_start_passes_the_rule(seed):
    draw = RA.random_arm(np.random.default_rng(seed))
    arm, q0 = draw.arm, np.array(draw.q0)
    lo, hi = arm.limits
    assert arm.n_joints == 6 and arm.convention == "standard" and draw.n_draws >= 1
    assert np.all(lo < hi) and np.all(hi - lo >= 1.2 * math.pi - 1e-12)
    assert np.all(q0 >= lo + RA.START_RULE["limit_margin"]) and np.all(q0 <= hi - RA.START_RULE["limit_margin"])
    p, J = arm_point_and_jacobian(arm, q0)
    assert np.linalg.svd(J, compute_uv=False)[-1] >= RA.START_RULE["min_sigma"]
    assert arm.base_height + p[2] >= RA.START_RULE["min_height"]
    assert 0.10 <= arm.tool <= 0.25 and 0.30 <= arm.a[1] <= 0.55
    assert all(m > 0 for m in arm.masses) and all(t >= 10.0 for t in arm.torque_limit)


def test_start_rule_refuses_a_singular_start():
    # the PUMA stretched straight up (q2 = pi/2, q3 = -pi/2 puts the forearm along the upper arm): sigma_min ~ 0
    q = np.array([0.0, math.pi / 2, -math.pi / 2, 0.0, 0.0, 0.0])
    assert np.linalg.svd(arm_point_and_jacobian(PUMA560, q)[1], compute_uv=False)[-1] < 0.05
    assert not RA.start_ok(PUMA560, q)
    assert RA.start_ok(PUMA560, np.array(S.STARTS["puma560"].q0))


def test_accept_hook_redraws_from_the_same_stream():
    seen = []

    def refuse_first(draw):
        seen.append(draw)
        return len(seen) > 1

    plain = RA.random_arm(np.random.default_rng(5))
    hooked = RA.random_arm(np.random.default_rng(5), refuse_first)
    assert seen[0] == plain  # the predicate saw the arm the plain call returns, then refused it
    assert hooked == seen[1] and hooked.arm != plain.arm and hooked.n_draws > plain.n_draws
    with pytest.raises(RuntimeError, match="passed the start rule"):
        RA.random_arm(np.random.default_rng(5), lambda draw: False, max_draws=50)
    with pytest.raises(TypeError, match="default_rng"):
        RA.random_arm(5)  # type: ignore[arg-type]


@pytest.mark.slow
def test_documented_acceptance_rate(capsys):
    from mobman_env.robots.__main__ import main

    main(["acceptance"])
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 2 and all("% of draws pass the start rule" in line for line in lines)
    doc = " ".join(RA.__doc__.split())
    for line in lines:
        assert line.split(" (seeds")[0] in doc


def test_cli_refuses_an_unknown_command(capsys):
    from mobman_env.robots.__main__ import main

    with pytest.raises(SystemExit):
        main(["tabel"])
    assert "invalid choice: 'tabel'" in capsys.readouterr().err


# --- starts ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["ur5", "panda"])
def test_chosen_starts_track_the_circle_with_the_arm_alone(name):
    arm, start = ROBOTS[name], S.STARTS[name]
    geo = S.circle_geometry(arm, start)
    assert geo["max_ratio"] < 0.95 and geo["sigma_min"] >= 0.15 and geo["margin"] >= 0.2
    rec = S.track(arm, start, S.TASK_SPECS["circle"], whole_body=False)
    assert rec["max_error"] < 1e-3 and rec["limit_hits"] == 0


def test_kinematic_ceiling_predicate():
    assert S.kinematic_ceiling(RA.RandomArm(UR5, S.STARTS["ur5"].q0, 1))
    assert not S.kinematic_ceiling(RA.RandomArm(UR5, S.STARTS["ur5"].q0, 1), tolerance=1e-6)


def test_task_specs_and_the_puma_start_are_todays():
    from mobman_env import PAPER_ARM_JOINT_POS, PAPER_BASE_POSE, TASKS

    names = ("Circle", "Line", "Lemniscate", "Random")
    assert list(S.TASK_SPECS.values()) == [TASKS[f"WheeledPuma-{k}-v0"] for k in names]
    assert S.STARTS["puma560"].q0 == PAPER_ARM_JOINT_POS and S.STARTS["puma560"].heading == PAPER_BASE_POSE[2]


def test_reach_of_the_puma():
    # wrist centre at hypot(d3, a2 + hypot(a3, d4)) from the shoulder, the tool pointing straight away from it
    p = RobotParams.nominal()
    expected = math.hypot(p.d3, p.a2 + math.hypot(p.a3, p.d4)) + p.tool
    assert S.reach(PUMA560) == pytest.approx(expected, abs=1e-6)


@pytest.mark.slow
def test_docstring_table_is_current():
    assert S.table() in S.__doc__


def test_the_scaled_family_scales_every_length_of_a_family_arm_by_one_factor():
    """random_scaled_arm draws s in SCALE_RANGE first, then random_arm's design; every DH a and d and the tool are
    s times the design's, twists, limits and the mount unchanged; the same stream gives the same arm."""
    for seed in range(5):
        rng = np.random.default_rng(seed)
        s = rng.uniform(*RA.SCALE_RANGE)
        design = RA.random_arm(rng)
        scaled = RA.random_scaled_arm(np.random.default_rng(seed))
        assert RA.SCALE_RANGE[0] <= s <= RA.SCALE_RANGE[1]
        np.testing.assert_allclose(scaled.arm.a, np.array(design.arm.a) * s, rtol=1e-15)
        np.testing.assert_allclose(scaled.arm.d, np.array(design.arm.d) * s, rtol=1e-15)
        assert scaled.arm.tool == pytest.approx(design.arm.tool * s, rel=1e-15)
        assert scaled.arm.alpha == design.arm.alpha and scaled.arm.joint_lower == design.arm.joint_lower
        assert scaled.arm.mount_offset == design.arm.mount_offset and scaled.q0 == design.q0
        assert scaled == RA.random_scaled_arm(np.random.default_rng(seed))


def test_a_modified_dh_arm_is_drawn_from_its_mount_to_joint_1():
    """The Panda's joint 1 sits d_0 = 0.333 m above its mount (modified DH), a length no arm link carries: the
    platform draws it, so the arm does not float above its pedestal in a picture (standard DH draws it in link 1)."""
    import re

    from mobman_env.params import RobotParams
    from mobman_env.urdf import ARM_RADIUS, urdf_string

    def base_arm_segments(arm) -> list[float]:
        base = urdf_string(RobotParams(arm=arm)).split('<link name="base_link">')[1].split("</link>")[0]
        return [float(x) for x in re.findall(rf'<cylinder radius="{ARM_RADIUS}" length="([^"]+)"', base)]

    assert base_arm_segments(PANDA) == pytest.approx([0.333], abs=1e-12)
    assert base_arm_segments(PUMA560) == base_arm_segments(UR5) == []
