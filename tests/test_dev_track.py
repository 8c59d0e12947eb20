"""MobMan-DevTrack-v0 (`train.dev_env`): the dev track's kinematic cells as one training env in the agent's
interface; the native vector env's `episode_sampler`; residual agents (training env, `sb3:` loading, batching);
the numpy actor of `policies.agents.sb3_actor`."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import mobman_env  # noqa: F401  (registers the robot ids)
import train  # (registers MobMan-DevTrack-v0)
from eval import conditions as C
from mobman_env.paths import TASK_SPECS
from policies.agents import agent_interface as interface
from train import dev_env as D


def _vec(n=6, **kwargs):
    return gym.make_vec(D.DEV_TRACK_ID, num_envs=n, autoreset_mode="SameStep", **kwargs)


def test_the_draws_are_the_dev_tracks_kinematic_cells_of_each_robot():
    for robot in D.ROBOTS:
        names = {group[0].condition for group in D.robot_draws(robot)}
        expected = {
            n
            for n in C.on_track("dev")
            if C.get(n).env_kwargs.get("dynamics") == "kinematic"
            and robot in C.get(n).robots
            and "control_freq" not in C.get(n).env_kwargs
        }
        assert names == expected and "default" in names and "lag100" in names and "rate50" not in names
    ladder = next(g for g in D.robot_draws("puma") if g[0].condition == "ladder-2.5s")
    assert [d.task for d in ladder] == ["random"] and ladder[0].options["path"]["duration"] == 2.5
    default = next(g for g in D.robot_draws("ur5") if g[0].condition == "default")
    assert [d.task for d in default] == list(TASK_SPECS) and default[0].options["model_error"] == 0.05


def test_vector_env_speaks_the_agent_interface_and_draws_per_episode():
    venv = _vec(6)
    assert isinstance(venv, D.DevTrackVectorEnv)
    assert venv.single_observation_space == interface.observation_space()
    assert venv.single_action_space.shape == (interface.N_ACTIONS,)
    assert venv.robot_index.tolist() == [0, 0, 1, 1, 2, 2]  # PUMA, UR5, Panda blocks
    obs, info = venv.reset(seed=3)
    assert set(obs) == set(interface.AGENT_OBS_KEYS) and obs["mask"].shape == (6, 9)
    assert obs["mask"][:, 6].tolist() == [0, 0, 0, 0, 1, 1]  # only the Panda has a 7th joint
    # every episode is drawn: over a few resets the robots' last draws cover several conditions and tasks
    draws = set()
    for seed in range(6):
        venv.reset(seed=seed)
        draws |= {(venv.samplers[k].last.condition, venv.samplers[k].last.task) for k in range(3)}
    assert len({c for c, _ in draws}) >= 4 and len({t for _, t in draws}) >= 2
    obs2, *_ = _vec(6).reset(seed=3)  # same seed, same episodes
    for k in obs:
        np.testing.assert_array_equal(obs[k], obs2[k])
    _, rewards, term, trunc, info = venv.step(np.zeros((6, 9), np.float32))
    assert rewards.shape == (6,) and info["tracking_error"].shape == (6,)
    with pytest.raises(ValueError, match=r"shape \(6, 9\)"):
        venv.step(np.zeros((6, 8), np.float32))
    venv.close()


def test_a_finished_episode_gives_its_final_observation_in_the_agents_view():
    # a 0.05 m error bound ends every robot's episode within a few steps of zero speed on a moving path
    venv = _vec(3, error_bound=0.01)
    venv.reset(seed=0)
    for _ in range(400):
        *_, term, trunc, info = venv.step(np.zeros((3, 9), np.float32))
        if (term | trunc).any():
            break
    done = np.flatnonzero(term | trunc)
    assert done.size and info["_final_obs"][done].all()
    assert set(info["final_obs"][done[0]]) == set(interface.AGENT_OBS_KEYS)


def test_refusals_name_the_value_and_the_fix():
    with pytest.raises(ValueError, match=r"draws \['model_error'\] per episode"):
        _vec(3, model_error=0.1)
    with pytest.raises(ValueError, match=r"num_envs >= 3"):
        _vec(2)
    with pytest.raises(ValueError, match="kinematic"):
        gym.make(D.DEV_TRACK_ID, dynamics="physics")
    with pytest.raises(ValueError, match="reset\\(options=...\\) is refused"):
        _vec(3).reset(options={"path": {"type": "circle"}})
    with pytest.raises(ValueError, match="not a built-in controller"):
        _vec(3, residual_base="os:system")
    with pytest.raises(ValueError, match="residual_scale must be > 0"):
        _vec(3, residual_base="qp", residual_scale=0.0)


def test_single_env_draws_a_robot_condition_and_task_and_passes_check_env():
    from gymnasium.utils.env_checker import check_env

    env = gym.make(D.DEV_TRACK_ID)
    seen = set()
    for seed in range(12):
        obs, info = env.reset(seed=seed)
        seen.add(info["robot"])
        assert info["condition"] in C.on_track("dev") and info["task_name"] in TASK_SPECS
        assert set(obs) == set(interface.AGENT_OBS_KEYS)
    assert seen == set(D.ROBOTS)
    check_env(env.unwrapped, skip_render_check=True)


def test_episode_sampler_gives_each_row_the_drawn_options():
    """A sampler that draws nothing gives every row exactly the episode that reset(options=...) gives."""
    options = {"path": dict(TASK_SPECS["line"]), "model_error": 0.2, "actuator_tau": 0.05}
    kw = {"num_envs": 4, "vectorization_mode": "vector_entry_point", "dynamics": "kinematic"}
    sampled = gym.make_vec("WheeledUR5-Circle-v0", episode_sampler=lambda rng: dict(options), **kw)
    plain = gym.make_vec("WheeledUR5-Circle-v0", **kw)
    a, _ = sampled.reset(seed=5)
    b, _ = plain.reset(seed=5, options=options)
    for _ in range(30):
        act = np.full((4, 8), 0.1, np.float32)
        a, *_ = sampled.step(act)
        b, *_ = plain.step(act)
    for k in a:
        np.testing.assert_array_equal(a[k], b[k])
    with pytest.raises(ValueError, match="episode_sampler must be a callable"):
        gym.make_vec("WheeledUR5-Circle-v0", episode_sampler=3, **kw)


def test_a_residual_env_shows_the_base_action_and_a_zero_residual_tracks_as_the_base():
    venv = _vec(6, residual_base="qp")
    assert interface.BASE_ACTION in venv.single_observation_space.spaces
    obs, _ = venv.reset(seed=11)
    errors = []
    for _ in range(300):
        obs, _, term, trunc, info = venv.step(np.zeros((6, 9), np.float32))
        errors.append(info["tracking_error"])
    assert np.abs(obs[interface.BASE_ACTION]).max() > 0
    # qp tracks every drawn cell of these rows within a few mm; the still robot of the plain env does not
    assert np.median(np.max(errors, axis=0)) < 0.006
    still = _vec(6)
    still.reset(seed=11)
    for _ in range(300):
        *_, info = still.step(np.zeros((6, 9), np.float32))
    assert np.median(info["tracking_error"]) > 0.05


@pytest.fixture(scope="module")
def residual_run(tmp_path_factory):
    """A residual agent over qp trained for one tiny rollout (6 robots x 8 steps): an untrained residual."""
    from train.run import run

    out = tmp_path_factory.mktemp("residual") / "run"
    config = train.TrainConfig(
        env_id=D.DEV_TRACK_ID,
        env_kwargs={"residual_base": "qp", "error_bound": 0.1},
        timesteps=48,
        n_envs=6,
        hyperparams={"n_steps": 8, "batch_size": 48, "n_epochs": 1},
        eval_freq=0,
        final_eval_episodes=1,
        out=str(out),
        progress_bar=False,
    )
    assert config.obs_keys[-1] == interface.BASE_ACTION and config.eval_env_id == "WheeledPuma-Circle-v0"
    assert "residual_base" not in config.eval_env_kwargs
    run(config)
    return out


def test_a_residual_agent_loads_with_its_base_and_batches_as_it_runs_single(residual_run):
    import policies
    from eval.rollout import make_env, rollout, rollout_batch

    env_id = "WheeledPanda-Lemniscate-v0"
    venv = gym.make_vec(env_id, num_envs=4, vectorization_mode="vector_entry_point", dynamics="kinematic")
    batched = policies.make(f"sb3:{residual_run}", venv)
    assert type(batched).__name__ == "BatchedAgent" and policies.knowledge_of(batched) == "nominal"
    recs = rollout_batch(venv, batched, 10_000)
    env = make_env(env_id, env_kwargs={"dynamics": "kinematic"})
    for i in range(2):
        single = rollout(env, policies.make(f"sb3:{residual_run}", env), 10_000 + i)[0]
        assert recs[i][0]["max_error_m"] == single["max_error_m"]
        assert single["knowledge"] == "nominal" and single["max_error_m"] < 0.006  # the base tracks
    env.close()


def test_a_residual_base_from_a_file_must_be_a_built_in(residual_run, tmp_path):
    import json
    import shutil

    import policies

    crafted = shutil.copytree(residual_run, tmp_path / "crafted")
    cfg = json.loads((crafted / "config.json").read_text())
    for bad in ("os:system", "../x", "qp:os.system"):
        cfg["env_kwargs"]["residual_base"] = bad
        (crafted / "config.json").write_text(json.dumps(cfg))
        with pytest.raises(ValueError, match="not a built-in controller"):
            policies.SB3Policy(crafted)
    cfg["env_kwargs"]["residual_base"] = "nosuchlaw"  # the right shape, no such controller: make refuses it
    (crafted / "config.json").write_text(json.dumps(cfg))
    env = gym.make("WheeledPuma-Circle-v0", dynamics="kinematic")
    with pytest.raises(ValueError, match="'nosuchlaw' is not a built-in controller"):
        policies.make(f"sb3:{crafted}", env)


def test_numpy_actor_equals_torch_and_does_not_depend_on_the_batch():
    from policies.agents.sb3 import SB3Policy
    from policies.agents.sb3_actor import numpy_actor

    agent = SB3Policy("ppo-circle")
    assert agent._actor is not None and numpy_actor(SB3Policy("sac-circle").model) is None
    rng = np.random.default_rng(0)
    space = agent.model.observation_space
    obs = {k: rng.standard_normal((64, *sp.shape)).astype(np.float32) for k, sp in space.spaces.items()}
    mine = agent._actor(obs)
    torch_action, _ = agent.model.predict(obs, deterministic=True)
    np.testing.assert_allclose(mine, torch_action, rtol=0, atol=1e-6)
    rows = np.stack([agent._actor({k: v[i] for k, v in obs.items()}) for i in range(64)])
    np.testing.assert_array_equal(mine, rows)  # bit for bit, row by row


def test_train_speed_races_the_recipe_and_reacher_and_writes_its_table(tmp_path):
    from train.cli import main

    assert main(["speed", "--steps", "1", "--repeats", "1", "--out", str(tmp_path)]) == 0
    import json

    res = json.loads((tmp_path / "train-speed.json").read_text())
    assert set(res["results"]) == {"mobman", "dev-track", "Reacher-v5"}
    assert res["results"]["Reacher-v5"]["ratio_to_reacher"] == 1.0
    assert all(r["steps"] == 16_384 for r in res["results"].values())  # one rollout of 256 envs x 64 steps
    assert "| Reacher-v5 |" in (tmp_path / "train-speed.md").read_text()
    assert main(["speed", "--steps", "0", "--out", str(tmp_path)]) == 2


def test_families_score_seeds_over_the_same_episodes_and_pick_the_median_seed():
    from train.families import families, markdown, parse_family

    def rec(spec, cond, seed, err):
        return {
            "policy": spec,
            "condition": cond,
            "env": "E",
            "seed": seed,
            "status": "ok",
            "max_error_m": err,
            "success": err <= 0.006,
        }

    errs = {"a": [0.001, 0.002, 0.0055], "b": [0.003, 0.004, 0.005], "c": [0.020, 0.030, 0.040]}
    records = [rec(s, c, 10_000, e) for s, es in errs.items() for c, e in zip(("x", "y", "z"), es)]
    fams = families(records, {"fam": ["a", "b", "c"]})["fam"]
    assert fams["n_seeds"] == 3 and fams["n_episodes"] == 9
    assert fams["per_seed_success_rate"] == pytest.approx([1.0, 1.0, 0.0])
    assert fams["median_seed_member"] == "b"  # per-seed IQMs (of 3 values: their means) 0.0028 / 0.004 / 0.030
    lo, hi = fams["success_rate_ci95"]
    assert lo < fams["success_rate"] < hi
    assert "| fam | 3 x 3 | 0 | 67%" in markdown({"fam": fams})
    with pytest.raises(ValueError, match="ran no episode"):
        families(records, {"fam": ["a", "missing"]})
    with pytest.raises(ValueError, match="NAME=SPEC"):
        parse_family("fam")


def test_every_shipped_model_card_equals_its_sources(monkeypatch):
    """The cards `mobman-train ship` wrote (folders with a card.json) regenerate equal from the committed files."""
    from pathlib import Path

    from train.model_card import write_card

    root = Path(__file__).resolve().parents[1]
    monkeypatch.chdir(root)  # card.json names its sources relative to the repository root
    folders = sorted(p for p in (root / "policies" / "models").iterdir() if (p / "card.json").is_file())
    assert {f.name for f in folders} >= {"ppo-dev", "residual-qp"}
    for folder in folders:
        assert write_card(folder, write=False) == (folder / "README.md").read_text(encoding="utf-8"), folder.name


def test_ship_refuses_an_unfinished_run(tmp_path):
    from train.model_card import ship

    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "model.zip").write_bytes(b"")
    with pytest.raises(ValueError, match=r"not a finished mobman-train run folder: \['vecnormalize.pkl'"):
        ship(tmp_path / "run", "x", tmp_path / "models", None, [], "abc")
