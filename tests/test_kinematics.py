"""Kinematics against finite differences, the URDF against the numpy FK, and the RobotParams rules."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from mobman_env import kinematics as K
from mobman_env.params import PERTURBED_FIELDS, RobotParams
from mobman_env.sim import Sim

NOMINAL = RobotParams.nominal()
PERTURBED = NOMINAL.perturbed(np.random.default_rng(3), 0.05)


def _random_config(rng, params):
    q = rng.uniform(params.joint_lower, params.joint_upper)
    pose = np.r_[rng.uniform(-2, 2, 2), rng.uniform(-4, 4)]
    return q, pose


@pytest.mark.parametrize("params", [NOMINAL, PERTURBED], ids=["nominal", "perturbed"])
def test_jacobians_match_finite_differences(params):
    rng = np.random.default_rng(0)
    h = 1e-6
    for _ in range(20):
        q, pose = _random_config(rng, params)
        u = rng.uniform(-1, 1, 8)
        # whole body: move every actuator for h seconds with the exact unicycle
        q1 = q + u[:6] * h
        pose1 = K.integrate_unicycle(params, pose, u[6:], h)
        fd = (K.ee_position(params, q1, pose1) - K.ee_position(params, q, pose)) / h
        J = K.whole_body_jacobian(params, q, pose[2])
        np.testing.assert_allclose(J @ u, fd, atol=2e-6)
        # paper's J: r_a_dot = [p_c_dot; 0] + J u
        pc_dot = (K.arm_base_xy(params, pose1) - K.arm_base_xy(params, pose)) / h
        Jp = K.paper_jacobian(params, q, pose[2])
        np.testing.assert_allclose(Jp @ u + np.r_[pc_dot, 0.0], fd, atol=2e-6)
        np.testing.assert_allclose(K.arm_base_jacobian(params, pose[2]) @ u, pc_dot, atol=2e-6)


def test_joint6_never_moves_the_point():
    rng = np.random.default_rng(1)
    for _ in range(10):
        q, pose = _random_config(rng, NOMINAL)
        assert np.abs(K.whole_body_jacobian(NOMINAL, q, pose[2])[:, 5]).max() < 1e-12


def test_unicycle_integration_is_exact_for_constant_wheel_speeds():
    pose = np.array([0.3, -0.2, 1.0])
    w = np.array([2.0, 5.0])
    one = K.integrate_unicycle(NOMINAL, pose, w, 1.0)
    many = pose
    for _ in range(1000):
        many = K.integrate_unicycle(NOMINAL, many, w, 1e-3)
    np.testing.assert_allclose(one, many, atol=1e-10)
    # straight line and spin on the spot
    np.testing.assert_allclose(K.integrate_unicycle(NOMINAL, np.zeros(3), [3.0, 3.0], 2.0), [1.2, 0, 0], atol=1e-12)
    spin = K.integrate_unicycle(NOMINAL, np.zeros(3), [-1.0, 1.0], 1.0)
    np.testing.assert_allclose(spin, [0, 0, 0.2 / 0.32], atol=1e-12)


@pytest.mark.parametrize("params", [NOMINAL, PERTURBED], ids=["nominal", "perturbed"])
def test_urdf_matches_numpy_fk(params):
    """PyBullet's `ee` link equals the numpy FK at 50 random configurations and base poses to 1e-6 m."""
    sim = Sim(0.01, 2)
    try:
        sim.reset(params, np.zeros(8), np.zeros(3))
        rng = np.random.default_rng(7)
        for _ in range(50):
            q, pose = _random_config(rng, params)
            sim.set_state(np.r_[q, rng.uniform(-3, 3, 2)], pose)
            ls = sim.client.getLinkState(sim.body, sim.ee_id, computeForwardKinematics=1)
            np.testing.assert_allclose(ls[0], K.ee_position(params, q, pose), atol=1e-6)
    finally:
        sim.close()


def test_perturbed_rule():
    rng = np.random.default_rng(0)
    draws = [NOMINAL.perturbed(rng, 0.05) for _ in range(300)]
    for name in PERTURBED_FIELDS:
        ratios = np.array([getattr(p, name) / getattr(NOMINAL, name) for p in draws])
        assert ratios.min() >= 1 - 0.15 - 1e-12 and ratios.max() <= 1 + 0.15 + 1e-12
        assert 0.035 < ratios.std() < 0.065
    # masses, limits, twists and the shoulder height never change
    for p in draws[:5]:
        for obj, ref, changed in _unchanged_fields(p, NOMINAL):
            for name in changed:
                assert getattr(obj, name) == getattr(ref, name), name
    assert NOMINAL.perturbed(rng, 0.0) == NOMINAL
    with pytest.raises(ValueError, match="rel_std"):
        NOMINAL.perturbed(rng, -0.1)
    assert NOMINAL.hash() != draws[0].hash() and NOMINAL.hash() == RobotParams().hash()


def test_perturbed_refuses_rel_std_at_which_a_length_can_reach_zero():
    """Factors are clipped to 1 +- 3 rel_std: at 1/3 the smallest is 0, so rel_std must stay below 1/3; at 0.3
    every factor of 1000 draws stays in [0.1, 1.9] (the extremes are reached: the clip is active)."""
    rng = np.random.default_rng(1)
    for bad in (1 / 3, 0.5, 5.0, True, "0.1"):
        with pytest.raises(ValueError, match=r"rel_std must be a finite number >= 0 and < 0.333333.*max\(0.1, 1 - 3"):
            NOMINAL.perturbed(rng, bad)
    ratios = np.array(
        [
            [getattr(p, n) / getattr(NOMINAL, n) for n in PERTURBED_FIELDS]
            for p in (NOMINAL.perturbed(rng, 0.3) for _ in range(1000))
        ]
    )
    assert ratios.min() == pytest.approx(0.1) and ratios.max() == pytest.approx(1.9)


@pytest.mark.parametrize("rel_std", [0.31, 0.33, 1 / 3 - 1e-12])
def test_a_worn_length_is_at_least_a_tenth_of_its_nominal_one(rel_std):
    """Just below 1/3 the clip 1 - 3 rel_std would let a length reach ~0 (4.5e-18 m, which PyBullet loads
    silently): every factor stays >= MIN_LENGTH_FACTOR = 0.1, which the draws reach; the upper clip is kept."""
    from mobman_env.params import MIN_LENGTH_FACTOR

    rng = np.random.default_rng(2)
    ratios = np.array(
        [
            [getattr(p, n) / getattr(NOMINAL, n) for n in PERTURBED_FIELDS]
            for p in (NOMINAL.perturbed(rng, rel_std) for _ in range(1000))
        ]
    )
    assert MIN_LENGTH_FACTOR == 0.1 and ratios.min() == pytest.approx(0.1, abs=1e-12)
    assert ratios.min() >= 0.1 - 1e-15 and ratios.max() == pytest.approx(1 + 3 * rel_std)
    assert (ratios <= 0.1 + 1e-12).mean() > 0.001  # the bound is active, not merely unreached


def test_the_length_bound_changes_no_robot_up_to_rel_std_0_3():
    """Up to rel_std = 0.3 (1 - 3 rel_std >= 0.1) the bound never acts: the draws are the plain clipped rule's."""
    for rel_std in (0.05, 0.2, 0.3):
        rng, ref = np.random.default_rng(4), np.random.default_rng(4)
        for _ in range(50):
            z = np.clip(ref.standard_normal(len(PERTURBED_FIELDS)), -3.0, 3.0)
            expected = NOMINAL._with_factors([1.0 + rel_std * zi for zi in z])
            assert NOMINAL.perturbed(rng, rel_std) == expected


def _unchanged_fields(p, ref):
    """(object, reference, names of the fields that perturbed/scaled leave alone) for the platform and the arm."""
    platform = [f.name for f in dataclasses.fields(RobotParams) if f.name not in PERTURBED_FIELDS and f.name != "arm"]
    arm = [f.name for f in dataclasses.fields(p.arm) if f.name not in ("a", "d", "tool", "mount_offset")]
    return [(p, ref, platform), (p.arm, ref.arm, arm)]


def test_scaled_multiplies_every_perturbed_length():
    p = NOMINAL.scaled(1.25)
    for name in PERTURBED_FIELDS:
        assert getattr(p, name) == getattr(NOMINAL, name) * 1.25, name
    for obj, ref, names in _unchanged_fields(p, NOMINAL):
        for name in names:
            assert getattr(obj, name) == getattr(ref, name), name
    with pytest.raises(ValueError, match="factor must be a finite number > 0"):
        NOMINAL.scaled(0.0)


def test_initial_geometry_of_the_paper_task():
    """theta(0) puts the tool point 0.675 m above the shoulder and slightly behind it; facing the circle
    (heading pi), the far side of the 0.4 m circle stays inside the arm's reach."""
    q0 = np.array([0, math.pi / 4, 0, 2 * math.pi / 3, -math.pi / 4, 0])
    f = K.arm_point(NOMINAL, q0)
    reach = math.hypot(NOMINAL.d3, NOMINAL.a2 + math.hypot(NOMINAL.a3, NOMINAL.d4 + NOMINAL.tool))
    start = K.ee_position(NOMINAL, q0, np.array([0, 0, math.pi]))
    far = start - np.array([0.8, 0, 0])
    shoulder = np.r_[K.arm_base_xy(NOMINAL, np.array([0, 0, math.pi])), NOMINAL.shoulder_height]
    assert np.linalg.norm(far - shoulder) < 0.95 * reach
    assert 0.6 < f[2] < 0.7


def test_shipped_nominal_urdf_is_generated_from_the_params():
    from mobman_env import urdf

    assert urdf.NOMINAL_URDF.read_text() == urdf.urdf_string(NOMINAL), (
        "mobman_env/assets/wheeled_puma560.urdf is stale: regenerate it with "
        "python -c 'from mobman_env import urdf, RobotParams; urdf.write_urdf(RobotParams(), urdf.NOMINAL_URDF)'"
    )
