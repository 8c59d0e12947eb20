"""The packed state has names (issue 35, STYLE 19): every layout covers its array exactly once, a field read by
name is the column the kernels use, the env's conditions are one frozen dataclass, and `env.step` reads a named
result."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mobman_env import engine as E
from mobman_env.batch import CONDITIONS, Conditions, StepResult
from mobman_env.env import WheeledPumaEnv
from mobman_env.sensors import SENSOR_KEYS
from mobman_env.vector import WheeledPumaVectorEnv
from policies.kernels import model_free as K

SHORT = {"type": "circle", "radius": 0.2, "duration": 0.5}


def _widths(columns, width: int) -> dict[str, int]:
    """Each field's width in a row of `width` columns: the distance to the next field (the last: to the end)."""
    ends = [*columns[1:], width]
    return {name: end - start for name, start, end in zip(columns._fields, columns, ends)}


def _cover(columns, width: int) -> np.ndarray:
    """How many fields of `columns` cover each of the array's `width` columns."""
    count = np.zeros(width, dtype=int)
    for name, n in _widths(columns, width).items():
        start = getattr(columns, name)
        count[start : start + max(n, 0)] += 1
    return count


@pytest.mark.parametrize("m", [7, 8, 9])
def test_every_layout_covers_its_array_exactly_once_with_the_documented_widths(m):
    layouts = {
        "prm": (E.PRM, E.P_LEN),
        "st": (E.state_columns(m), E.s_len(m)),
        "io": (E.io_columns(m), E.io_len(m)),
        "sensors": (E.sensor_columns(m), E.n_sensor(m)),
    }
    for name, (columns, width) in layouts.items():
        assert columns[0] == 0, name
        assert (_cover(columns, width) == 1).all(), f"{name}: a gap or an overlap"
    assert _widths(E.PRM, E.P_LEN) == {**dict.fromkeys(E.PRM._fields, 1), "spare": 2, "path": E.PATH_LEN}
    assert _widths(E.state_columns(m), E.s_len(m)) == {**dict.fromkeys(E.StateColumns._fields, 1), "q": m, "u": m}
    io = _widths(E.io_columns(m), E.io_len(m))
    wide = {"action": m, "noise": E.n_sensor(m), "phys_q": m, "phys_q_dot": m, "phys_pos": 3, "phys_quat": 4}
    wide |= {"phys_lin_vel": 3, "phys_ang_vel": 3, "ee_pos_true": 3, "motor_speed": m, "readings": E.n_sensor(m)}
    assert io == {**dict.fromkeys(E.IoColumns._fields, 1), **wide}
    sensors = _widths(E.sensor_columns(m), E.n_sensor(m))
    assert tuple(sensors) == SENSOR_KEYS
    assert sensors == {"ee_pos": 3, "ee_vel": 3, "arm_base_pos": 2, "arm_base_vel": 2, "base_yaw": 1} | {
        "joint_pos": m,
        "joint_vel": m,
    }
    assert len(E.ARM) == E.ARM_ROWS == 8 and list(E.ARM) == list(range(8))


def test_the_named_layouts_keep_the_columns_of_release_0_3():
    """The names moved no column (the pinned results depend on none of them, but other code's packed arrays do)."""
    m = 8
    assert (E.PRM.tool, E.PRM.actuator_tau, E.PRM.n_steps, E.PRM.noisy, E.PRM.path, E.P_LEN) == (0, 6, 12, 17, 20, 168)
    s = E.state_columns(m)
    assert (s.u, s.x, s.steps, s.pitch, E.s_len(m)) == (m, 2 * m, 2 * m + 3, 2 * m + 7, 2 * m + 8)
    io = E.io_columns(m)
    assert (io.noise, io.phys_q, io.reward) == (m, 3 * m + 11, 5 * m + 24)
    assert io.motor_speed == io.reward + E.O_U and io.readings == 6 * m + 39
    assert (io.tipped_over - io.reward, io.ee_pos_true - io.reward) == (12, 4)


def test_a_field_read_by_name_is_the_column_the_kernels_use_on_a_stepped_batch():
    env = WheeledPumaVectorEnv(3, path=SHORT, actuator_tau=0.05, wear_rate=0.01, obs_noise=1e-3)
    try:
        env.reset(seed=3, options={"actuator_tau": 0.02})
        for _ in range(4):
            env.step(np.full((3, 8), 0.7))
        b = env._batch
        m = b.m
        prm, st, io = b.named("prm"), b.named("st"), b.named("io")
        assert prm["actuator_tau"].tolist() == [0.02] * 3 == b.prm[:, 6].tolist()
        assert prm["wear_rate"].tolist() == [0.01] * 3 == b.prm[:, 5].tolist()
        assert (prm["path"] == b.prm[:, 20:]).all()
        assert st["steps"].tolist() == [4.0] * 3 == b.st[:, 2 * m + 3].tolist()
        assert (st["q"] == b.st[:, :m]).all() and (st["u"] == b.st[:, m : 2 * m]).all()
        out = 5 * m + 24
        assert io["tracking_error"].tolist() == b.io[:, out + 3].tolist()
        assert (io["ee_pos_true"] == b.io[:, out + 4 : out + 7]).all()
        assert (io["motor_speed"] == b.io[:, out + 15 : out + 15 + m]).all()
        assert (io["readings"] == b.io[:, 6 * m + 39 :]).all()
        prm["obs_noise"][1] = 0.25  # a view: writing by name writes the kernels' column
        assert b.prm[1, 13] == 0.25
        assert [env.true_actuator_tau(i) for i in range(3)] == [0.02] * 3
    finally:
        env.close()


def test_the_conditions_are_one_frozen_dataclass_that_round_trips_the_constructor():
    given = {
        "model_error": 0.1,
        "obs_noise": 1e-3,
        "obs_noise_vel": 1e-2,
        "obs_noise_joint_vel": 0.05,
        "obs_noise_yaw": 2e-3,
        "obs_delay": 2,
        "wear_rate": 0.01,
        "actuator_tau": 0.03,
    }
    assert CONDITIONS == tuple(given) == tuple(f.name for f in dataclasses.fields(Conditions))
    env = WheeledPumaEnv(dynamics="kinematic", path=SHORT, **given)
    try:
        assert env.conditions == Conditions(**given)
        assert dataclasses.asdict(env.conditions) == given
        assert {k: getattr(env, k) for k in CONDITIONS} == given
        with pytest.raises(dataclasses.FrozenInstanceError):
            env.conditions.actuator_tau = 0.5  # type: ignore[misc]
        with pytest.raises(AttributeError):
            env.actuator_tau = 0.5  # read-only: the one copy is `conditions`
        # the defaults of the dataclass are the constructor's
        default = WheeledPumaEnv(dynamics="kinematic")
        assert default.conditions == Conditions()
        default.close()
        # a reset option overrides one condition for one episode; the env's own stay
        env.reset(seed=0, options={"actuator_tau": 0.07})
        assert env.true_actuator_tau == 0.07 and env.conditions.actuator_tau == 0.03
        env.reset(seed=0)
        assert env.true_actuator_tau == 0.03
    finally:
        env.close()


def test_env_step_reads_a_named_result_with_the_documented_fields():
    assert StepResult._fields == (
        "reward",
        "tracking",
        "effort",
        "tracking_error",
        "ee_pos_true",
        "action_clipped",
        "terminated",
        "truncated",
        "n_clipped",
        "joint_limit_hits",
        "tipped_over",
    )
    # `RobotBatch.result` reads io's results block in one go: its fields are StepResult's, in order
    io = E.io_columns(8)
    block = E.IoColumns._fields[E.IoColumns._fields.index("reward") : E.IoColumns._fields.index("tipped_over") + 1]
    assert block == StepResult._fields and io.tipped_over - io.reward == len(block) + 1  # ee_pos_true: 3 wide
    env = WheeledPumaEnv(dynamics="kinematic", path=SHORT)
    try:
        env.reset(seed=1)
        _, reward, terminated, truncated, info = env.step(np.full(8, 1.5, dtype=np.float32))
        r = env._batch.result(0)
        assert isinstance(r, StepResult)
        assert (reward, terminated, truncated) == (r.reward, r.terminated, r.truncated)
        assert type(reward) is float and type(terminated) is bool and type(r.n_clipped) is int
        assert r.reward == r.tracking + r.effort
        assert info["reward_terms"] == {"tracking": r.tracking, "effort": r.effort}
        assert info["tracking_error"] == r.tracking_error and (info["ee_pos_true"] == r.ee_pos_true).all()
        assert info["action_clipped"] is True and info["n_clipped"] == r.n_clipped == 1
        assert info["joint_limit_hits"] == r.joint_limit_hits and info["tipped_over"] is r.tipped_over is False
    finally:
        env.close()


@pytest.mark.parametrize("kind", [K.KALMAN, K.STRUCTURED, K.BROYDEN, K.RLS])
@pytest.mark.parametrize("max_delay", [0, 3])
def test_the_model_free_laws_blocks_cover_its_float_state_exactly_once(kind, max_delay):
    n = 8
    lay = K.layout(n, max_delay, kind)
    named = K.blocks(lay)
    assert len(lay) == K.LAY_LEN == len(K.FloatBlocks._fields) and named.q0 == 0
    assert all(lay[getattr(K.LAY, f)] == getattr(named, f) for f in K.FloatBlocks._fields)
    width = named.length
    widths = _widths(named, width)
    assert widths.pop("length") == 0
    assert sum(widths.values()) == width and all(w > 0 for w in widths.values()), "a gap or an overlap"
    d = max_delay + 1
    assert widths["hist"] == d * n and widths["lag_ms"] == d + K.N_LAGS and widths["q0"] == n - 2
    assert widths["probe_a"] == n * n and widths["j_probe"] == 3 * n == widths["probe_b"]
    assert widths["est"] == K.est_layout(kind, n)[1]
