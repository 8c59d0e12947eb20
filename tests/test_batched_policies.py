"""Batched policies (`policies.make(spec, vector_env)`): robot i's actions equal a single-env policy reset with
`policy_seed(S + i)` on the same observations (bit for bit here: a vectorised law's single-env class runs the same
kernel with N = 1, and the other specs loop their single-env rows), and `episode_start` re-initialises its rows
only. Seeds >= 10,000."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import policies
from mobman_env import TASKS, WheeledPumaEnv
from mobman_env import kinematics as K
from mobman_env.params import RobotParams
from mobman_env.vector import _row_info
from policies.base import policy_seed
from policies.batched import BatchedController, BatchedPolicy, _RobotView
from policies.kernels.shared import ModelJacobians, damped_pinv_apply_rows

SPECS = ("zero", "random", "jmpi", "clik", "clik-full", "oracle", "nnbc", "nnbc-plus", "broyden", "rls", "mpc-oracle")
ENV_ID = "WheeledPuma-Lemniscate-v0"


def _batched_and_singles(spec: str, venv, envs: list, seed: int):
    """`spec` built for the vector env and for each single env, all reset with the vector seed S (single i:
    env seed S + i, policy seed policy_seed(S + i)): (batched, singles, vector obs, single obs list)."""
    batched = policies.make(spec, venv)
    singles = [policies.make(spec, env) for env in envs]
    obs, info = venv.reset(seed=seed)
    batched.reset(obs, info, seed=seed)
    single_obs = []
    for i, (env, pol) in enumerate(zip(envs, singles)):
        o, inf = env.reset(seed=seed + i)
        pol.reset(o, inf, seed=policy_seed(seed + i))
        single_obs.append(o)
    return batched, singles, obs, single_obs


@pytest.mark.parametrize("spec", SPECS)
def test_rows_equal_single_policies(spec):
    n, seed, steps = 3, 10_000, 60
    path = dict(TASKS[ENV_ID], duration=0.4)  # 40 steps: the episodes end and autoreset
    venv = gym.make_vec(ENV_ID, num_envs=n, vectorization_mode="vector_entry_point", dynamics="kinematic", path=path)
    envs = [WheeledPumaEnv(dynamics="kinematic", path=path) for _ in range(n)]
    batched, singles, obs, single_obs = _batched_and_singles(spec, venv, envs, seed)
    assert isinstance(batched, BatchedPolicy) and batched.num_envs == n
    starts = np.zeros(n, dtype=bool)
    for t in range(steps):
        if t == 25:
            starts[1] = True  # re-initialise row 1 only, mid-episode
        actions, _ = batched.predict(obs, episode_start=starts)
        assert actions.shape == (n, 8) and actions.dtype == np.float32
        for i, pol in enumerate(singles):
            a, _ = pol.predict(single_obs[i], episode_start=np.array([starts[i]]))
            assert np.array_equal(actions[i], a), (spec, t, i, actions[i], a)
        obs, *_ = venv.step(actions)
        for i, env in enumerate(envs):
            if single_obs[i] is None:
                single_obs[i], _ = env.reset()
            else:
                single_obs[i], _, te, tr, _ = env.step(actions[i])
                if te or tr:
                    single_obs[i] = None
        # rows that autoreset this step: the vector env returns the new episode's first obs on the next step
        starts = np.array([o is None for o in single_obs])
        for i in np.flatnonzero(starts):
            single_obs[i], _ = envs[i].reset()
        if starts.any():
            obs, *_ = venv.step(np.zeros((n, 8), dtype=np.float32))  # the autoreset step (actions ignored)
    venv.close()
    for env in envs:
        env.close()


def test_bad_batches_raise():
    venv = gym.make_vec(ENV_ID, num_envs=2, vectorization_mode="vector_entry_point", dynamics="kinematic")
    pol = policies.make("clik", venv)
    obs, _ = venv.reset(seed=10_100)
    with pytest.raises(ValueError, match="leading axis of 2"):
        pol.predict({k: v[:1] for k, v in obs.items()})
    with pytest.raises(ValueError, match="list of 2 seeds"):
        pol.reset(obs, seed=[1, 2, 3])
    venv.close()


#: the specs with a vectorised law (`policies.batched.BatchedController`); the others loop their rows
VECTORISED = ("zero", "random", "qp", "qp-oracle", "calib-qp", "mpc", "mpc-oracle") + tuple(
    f"{law}{form}" for law in ("jmpi", "clik", "oracle", "nnbc") for form in ("", "-full")
)
#: the model-free laws of `policies.laws.nnbc_plus.ModelFreeLaw` (one numba kernel over the rows)
MODEL_FREE = ("nnbc-plus", "nnbc-plus-wb", "broyden", "rls", "nnbc-plus:formulation=paper,j0_noise=0.3")


def _venv(env_id: str, n: int):
    return gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", dynamics="kinematic")


@pytest.mark.parametrize("env_id", ["WheeledPuma-Circle-v0", "WheeledPuma-Line-v0"])
@pytest.mark.parametrize("spec", VECTORISED + MODEL_FREE)
def test_vectorised_law_equals_single_policies(spec, env_id):
    """N = 5 robots for 200 steps driven by the batched actions: row i's action equals a single policy's (built for
    robot i, reset with policy_seed(S + i)) on the same observation to 1e-9 (bit for bit, in fact: the single
    policy runs the same kernel with N = 1), Jacobian estimates included; `episode_start` on rows 1 and 3 at step
    60 restarts those rows only (nnbc: they probe again while the others run the ZNN law)."""
    n, seed = 5, 10_200
    venv = _venv(env_id, n)
    batched = policies.make(spec, venv)
    assert isinstance(batched, BatchedController) and batched.num_envs == n
    singles = [policies.make(spec, _RobotView(venv, i)) for i in range(n)]
    obs, info = venv.reset(seed=seed)
    batched.reset(obs, info, seed=seed)
    for i, pol in enumerate(singles):  # row i's reset info, as a single env hands it out (mpc previews its path)
        pol.reset({k: v[i] for k, v in obs.items()}, _row_info(info, i), seed=policy_seed(seed + i))
    restart = np.isin(np.arange(n), [1, 3])
    for t in range(200):
        starts = restart if t == 60 else None
        actions, _ = batched.predict(obs, episode_start=starts)
        assert actions.shape == (n, 8) and actions.dtype == np.float32
        for i, pol in enumerate(singles):
            a, _ = pol.predict(
                {k: v[i] for k, v in obs.items()}, episode_start=None if starts is None else starts[i : i + 1]
            )
            np.testing.assert_allclose(actions[i], a, rtol=0, atol=1e-9, err_msg=f"{spec} step {t} row {i}")
            J_row, J_single = batched.rows[i].jacobian_estimate, pol.jacobian_estimate
            assert (J_row is None) == (J_single is None), (t, i)
            if J_row is not None:
                np.testing.assert_allclose(J_row, J_single, rtol=0, atol=1e-9)
        obs, _, term, trunc, _ = venv.step(actions)
        assert not (term | trunc).any()
    if spec.startswith("nnbc"):
        steps = batched.steps  # the restarted rows count their steps from their new start
        assert steps.tolist() == [200, 140, 200, 140, 200]
    if spec in MODEL_FREE:  # bit for bit, the commands and the estimates: the same kernel with N = 1
        for i, pol in enumerate(singles):
            np.testing.assert_array_equal(batched.last_u[i], pol.last_u)
            np.testing.assert_array_equal(batched.J_hat_row(i), pol.J_hat)
            np.testing.assert_array_equal(batched.Jdot_hat_row(i), pol.Jdot_hat)
    venv.close()


@pytest.mark.parametrize("spec", ["nnbc", "clik", "oracle", "random", "qp-oracle"])
def test_one_robot(spec):
    """N = 1: the batched law of a one-robot vector env acts as the single policy of that robot."""
    venv = _venv("WheeledPuma-Circle-v0", 1)
    batched = policies.make(spec, venv)
    single = policies.make(spec, _RobotView(venv, 0))
    obs, info = venv.reset(seed=10_300)
    batched.reset(obs, info, seed=10_300)
    single.reset({k: v[0] for k, v in obs.items()}, None, seed=policy_seed(10_300))
    for _ in range(40):
        actions, _ = batched.predict(obs)
        a, _ = single.predict(obs)  # a batch of one, as a DummyVecEnv passes it
        assert actions.shape == a.shape == (1, 8)
        np.testing.assert_array_equal(actions, a)
        obs, *_ = venv.step(actions)
    venv.close()


class LoopedZero:
    """A user's policy (a `module:attr` spec): no vectorised law, so a vector env loops one per row."""

    def __init__(self, env):
        self.n = env.action_space.shape[0]

    def reset(self, obs, info=None, *, seed=None): ...

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        return np.zeros(self.n, dtype=np.float32), state


@pytest.mark.parametrize("spec", [f"{__name__}:LoopedZero"])
def test_other_specs_loop_their_rows(spec):
    venv = _venv(ENV_ID, 2)
    pol = policies.make(spec, venv)
    assert isinstance(pol, BatchedPolicy) and not isinstance(pol, BatchedController) and len(pol.rows) == 2
    venv.close()


@pytest.mark.parametrize("spec", MODEL_FREE[:4])
def test_model_free_specs_are_vectorised_laws(spec):
    venv = _venv(ENV_ID, 2)
    pol = policies.make(spec, venv)
    assert isinstance(pol, BatchedController) and len(pol.rows) == 2
    venv.close()


def test_model_jacobians_equal_the_single_kinematics():
    """`policies.kernels.shared.ModelJacobians` (batched `mobman_env.vector_kinematics`) equals `mobman_env.kinematics`
    bit for bit, per row of worn robots, for the paper's and the whole-body Jacobian (what lets the single-env
    laws evaluate their one row with `mobman_env.kinematics`)."""
    rng = np.random.default_rng(10_400)
    nominal = RobotParams.nominal()
    for _ in range(20):
        robots = [nominal.perturbed(rng, 0.05) for _ in range(5)]
        q, yaw = rng.uniform(-3.0, 3.0, (5, 8)), rng.uniform(-7.0, 7.0, (5, 1))
        model = ModelJacobians(5, robots.__getitem__)
        model.load(range(5))
        for full, single in ((False, K.paper_jacobian), (True, K.whole_body_jacobian)):
            J = model(q, yaw, full)
            for i, p in enumerate(robots):
                np.testing.assert_array_equal(J[i], single(p, q[i, :6], float(yaw[i, 0])))
            np.testing.assert_array_equal(model(q[2:3], yaw[2:3], full, rows=[2])[0], J[2])


def test_damped_pinv_rows_equal_one_row_at_a_time():
    """The 3 x 3 algebra on (N,) arrays equals the one on floats (N = 1), row by row, damped rows included."""
    rng = np.random.default_rng(10_500)
    J = rng.normal(size=(64, 3, 8)) * np.geomspace(1e-3, 1.0, 64)[:, None, None]  # some below the threshold
    v = rng.normal(size=(64, 3))
    u = damped_pinv_apply_rows(J, v, 0.02, 0.02)
    for i in range(64):
        np.testing.assert_array_equal(u[i], damped_pinv_apply_rows(J[i : i + 1], v[i : i + 1], 0.02, 0.02)[0])


def test_nnbc_rows_stay_exact_where_the_damping_acts():
    """Over most of a Line-v0 episode J_hat degenerates and the damping of its pseudo-inverse acts (sigma_min below
    0.02 m/rad): there the command depends on the last bit of sigma_min, which the batched rows take from the
    same float path as the single policy, so the chaotic law stays bit-identical (np.arccos alone would not)."""
    n, seed = 3, 10_000
    venv = _venv("WheeledPuma-Line-v0", n)
    batched = policies.make("nnbc", venv)
    singles = [policies.make("nnbc", _RobotView(venv, i)) for i in range(n)]
    obs, info = venv.reset(seed=seed)
    batched.reset(obs, info, seed=seed)
    for i, pol in enumerate(singles):
        pol.reset({k: v[i] for k, v in obs.items()}, None, seed=policy_seed(seed + i))
    damped = 0
    for _ in range(1200):
        actions, _ = batched.predict(obs)
        for i, pol in enumerate(singles):
            np.testing.assert_array_equal(actions[i], pol.predict({k: v[i] for k, v in obs.items()})[0])
        damped += int((np.linalg.svd(batched.J_hat, compute_uv=False)[:, -1] < 0.02).sum())
        obs, *_ = venv.step(actions)
    assert damped > 50  # the property was exercised
    venv.close()


def test_stacked_policy_rows_equal_their_own_batched_policies():
    """`StackedPolicy` over row blocks of one vector env acts, row for row, as each block's batched policy on a
    vector env of its own (same seeds); bad part layouts raise."""
    from policies.stacked import StackedPolicy, VectorEnvRows

    seeds = [10_600, 10_601, 10_602]
    venv = _venv(ENV_ID, 6)
    blocks = ((slice(0, 3), "clik"), (slice(3, 6), "nnbc-plus"))
    stacked = StackedPolicy([(policies.make(spec, VectorEnvRows(venv, rows)), rows) for rows, spec in blocks])
    own = [(_venv(ENV_ID, 3), spec) for _, spec in blocks]
    obs, info = venv.reset(seed=seeds * 2)
    stacked.reset(obs, info, seed=[policy_seed(s) for s in seeds * 2])
    pols = []
    for v, spec in own:
        pol = policies.make(spec, v)
        o, i = v.reset(seed=seeds)
        pol.reset(o, i, seed=[policy_seed(s) for s in seeds])
        pols.append((v, pol, o))
    for _ in range(30):
        actions, _ = stacked.predict(obs)
        for k, ((rows, _), (v, pol, o)) in enumerate(zip(blocks, pols)):
            a, _ = pol.predict(o)
            np.testing.assert_array_equal(actions[rows], a)
            pols[k] = (v, pol, v.step(a)[0])
        obs = venv.step(actions)[0]
    assert stacked.row_us.shape == (6,) and (stacked.row_us > 0).all()
    assert len(stacked.rows) == 6 and stacked.rows[4].jacobian_estimate is not None  # nnbc-plus row, probe done
    with pytest.raises(ValueError, match="consecutive non-empty row slices"):
        StackedPolicy([(stacked.parts[0][0], slice(0, 3)), (stacked.parts[1][0], slice(4, 6))])
    venv.close()
    for v, _ in own:
        v.close()


# --- sb3:, module:attr and mobman's SyncVectorEnvs (physics mode, random arm) --------------------------------
USER_POLICY = '''
import numpy as np


class Pol:
    """A user's proportional law on the position error, with its own seeded dither."""

    def __init__(self, env):
        self.n = env.action_space.shape[0]
        self.rng = np.random.default_rng(0)

    def reset(self, obs, info=None, *, seed=None):
        self.rng = np.random.default_rng(seed)

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        a = np.zeros(self.n, dtype=np.float32)
        a[:3] = 5.0 * (obs["target_pos"] - obs["ee_pos"]) + 0.01 * self.rng.standard_normal(3)
        return np.clip(a, -1, 1), state
'''
SHORT = {"type": "circle", "radius": 0.1, "duration": 1.0}


@pytest.mark.parametrize(
    "env_id, dynamics",
    [
        ("WheeledPuma-Circle-v0", "kinematic"),  # the native vector env
        ("WheeledPuma-Circle-v0", "physics"),  # a SyncVectorEnv of single envs
        ("WheeledRandomArm-Circle-v0", "kinematic"),  # a SyncVectorEnv of single envs
    ],
)
@pytest.mark.parametrize("spec", ["sb3:sac-circle", "userpol_batched:Pol", "clik", "nnbc"])
@pytest.mark.filterwarnings("ignore:the agent .* was trained on:UserWarning")  # the PUMA agent on the random arm
def test_every_spec_on_every_mobman_vector_env_equals_its_single_policies(
    tmp_path, monkeypatch, spec, env_id, dynamics
):
    if spec.startswith("sb3:"):
        pytest.importorskip("stable_baselines3")
    (tmp_path / "userpol_batched.py").write_text(USER_POLICY)
    monkeypatch.syspath_prepend(str(tmp_path))
    n, seed, steps = 2, 10_500, 12
    venv = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", dynamics=dynamics, path=SHORT)
    envs = [gym.make(env_id, dynamics=dynamics, path=SHORT) for _ in range(n)]
    try:
        batched, singles, obs, single_obs = _batched_and_singles(spec, venv, envs, seed)
        for t in range(steps):
            actions, _ = batched.predict(obs)
            assert actions.shape == (n, 8) and actions.dtype == np.float32
            for i, pol in enumerate(singles):
                a, _ = pol.predict(single_obs[i])
                assert np.array_equal(actions[i], a), (spec, t, i)
                single_obs[i], *_ = envs[i].step(actions[i])
            obs, *_ = venv.step(actions)
    finally:
        venv.close()
        for env in envs:
            env.close()


def test_async_vector_env_is_refused_with_the_fix():
    venv = gym.make_vec("WheeledPuma-Circle-v0", num_envs=2, vectorization_mode="async", dynamics="kinematic")
    try:
        with pytest.raises(
            TypeError, match=r"AsyncVectorEnv.*native vector env or a SyncVectorEnv.*vector_entry_point"
        ):
            policies.make("clik", venv)
    finally:
        venv.close()


@pytest.mark.parametrize("spec", ["clik", "nnbc", "nnbc-plus", "zero"])
def test_reset_with_fewer_rows_than_robots_is_refused_with_the_shapes(spec):
    venv = _venv(ENV_ID, 3)
    pol = policies.make(spec, venv)
    obs, info = venv.reset(seed=10_600)
    with pytest.raises(ValueError, match=r"reset of a batched policy of 3 rows .*leading axis of 3.*\(2, 3\)"):
        pol.reset({k: v[:2] for k, v in obs.items()}, info, seed=10_600)
    venv.close()


def model_free_digests(steps: int = 300) -> list[str]:
    """sha256 of the commands (last_u, float64 bytes) of each model-free spec on a linear plant r_dot = J u (8
    actuators, a turning platform's wheels in J's last columns) over `steps` steps: past the probe, the settling of
    the actuator model and the first block of dither signs."""
    import hashlib

    from policies.base import EnvFacts
    from policies.registry import build_config, parse_spec

    facts = EnvFacts(dt=0.01, action_scale=(3.0,) * 6 + (10.0, 10.0), obs_keys=())
    J = 0.3 * np.random.default_rng(7).standard_normal((3, 8))
    out = []
    for spec in MODEL_FREE + ("nnbc-plus:formulation=whole_body,measurement=position",):
        name, options = parse_spec(spec)
        entry = policies.registry._REGISTRY[name]
        cls, cfg_cls = policies.registry._load_entry(name, entry)
        pol = cls(facts, build_config(cfg_cls, {**entry.preset, **options}, spec), seed=3)
        q, r, u, h = np.zeros(8), np.zeros(3), np.zeros(8), hashlib.sha256()
        for k in range(steps):
            t = 0.01 * k
            obs = {
                "ee_pos": r, "ee_vel": J @ u, "arm_base_pos": np.zeros(2), "arm_base_vel": np.zeros(2),
                "joint_pos": q, "joint_vel": u, "target_pos": 0.05 * np.array([np.sin(t), 1 - np.cos(t), 0.0]),
                "target_vel": 0.05 * np.array([np.cos(t), np.sin(t), 0.0]), "base_yaw": np.array([0.1 * t]),
            }  # fmt: skip
            action, _ = pol.predict(obs)
            u = np.asarray(action, dtype=float) * facts.scale
            h.update(np.asarray(pol.last_u, dtype=float).tobytes())
            q, r = q + 0.01 * u, r + 0.01 * (J @ u)
        out.append(h.hexdigest())
    return out


@pytest.mark.slow
def test_the_model_free_law_as_plain_python_gives_the_compiled_bits():
    """`policies.kernels.model_free` run as plain Python (`NUMBA_DISABLE_JIT=1`) issues the compiled kernel's
    commands bit for bit (the kernels are plain float code: no fast-math, no reassociation)."""
    import json
    import os
    import subprocess
    import sys
    from pathlib import Path

    code = (
        f"import json, sys; sys.path.insert(0, {str(Path(__file__).parent)!r}); "
        "from test_batched_policies import model_free_digests; print(json.dumps(model_free_digests()))"
    )
    env = {**os.environ, "NUMBA_DISABLE_JIT": "1"}
    proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert json.loads(proc.stdout.strip().splitlines()[-1]) == model_free_digests()


def _known_specs() -> list[str]:
    from policies.registry import KNOWN_POLICIES

    return list(KNOWN_POLICIES)


@pytest.mark.parametrize("key", ["joint_pos", "ee_pos", "base_yaw", "target_pos"])
@pytest.mark.parametrize("spec", _known_specs())
def test_a_non_finite_observation_row_is_that_rows_problem(spec, key, capfd):
    """One robot's NaN or inf reading gives that robot a non-finite action (the env refuses it, naming the robot)
    and leaves the other rows' actions as they are, bit for bit: no LinAlgError (`qp`, `calib-qp`, `clik` once
    failed the whole batch on a NaN joint angle or heading, with LAPACK's complaint on stderr)."""
    venv = _venv(ENV_ID, 3)
    clean, dirty = policies.make(spec, venv), policies.make(spec, venv)
    try:
        obs, info = venv.reset(seed=10_500)
        for pol in (clean, dirty):
            pol.reset(obs, info, seed=10_500)
        bad = {k: v.copy() for k, v in obs.items()}
        bad[key][1, 0] = np.nan if key != "base_yaw" else np.inf
        a_clean, a_dirty = clean.predict(obs)[0], dirty.predict(bad)[0]
    finally:
        venv.close()
    assert np.array_equal(a_clean[[0, 2]], a_dirty[[0, 2]])
    assert np.isfinite(a_dirty[[0, 2]]).all()
    assert "DLASCL" not in capfd.readouterr().err


@pytest.mark.parametrize("spec", _known_specs())
def test_a_missing_observation_key_is_named_with_the_fix(spec):
    """An observation without a key the law reads (a filtered or renamed dict) raised a bare KeyError naming the
    key only: it names the key, the keys the policy reads and the fix, for the batched policy (reset and predict)
    and the single one. A law that reads no key (`zero`, `random`) does not care."""
    import re

    venv = _venv(ENV_ID, 2)
    env = WheeledPumaEnv(dynamics="kinematic")
    try:
        batched, single = policies.make(spec, venv), policies.make(spec, env)
        obs, info = venv.reset(seed=10_600)
        keys = tuple(getattr(batched, "uses_keys", ()))
        drop = keys[-1] if keys else "ee_pos"
        partial = {k: v for k, v in obs.items() if k != drop}
        single_partial = {k: v[0] for k, v in partial.items()}
        calls = [
            lambda: batched.reset(partial, info, seed=10_600),
            lambda: batched.predict(partial),
            lambda: single.reset(single_partial, None, seed=1),
            lambda: single.predict(single_partial),
        ]
        for call in calls:
            if not keys:
                call()
                continue
            message = rf"the observation has no '{drop}': this policy reads \[.*'{drop}'.*\], the observation holds"
            with pytest.raises(ValueError, match=message) as info_:
                call()
            assert "pass the env's whole Dict observation" in str(info_.value)
            assert re.search(r"holds \['", str(info_.value))
    finally:
        venv.close()
        env.close()
