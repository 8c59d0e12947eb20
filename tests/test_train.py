"""mobman-train: config round trip, bad arguments, smoke training of every algorithm, reload through SB3Policy,
resume, Ctrl-C, determinism. Tiny budgets (a few hundred steps) on a 1 s path in kinematic mode."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from test_eval_helpers import terminal_sigint

from train.algos import ALGOS
from train.cli import main
from train.config import LEARNING_ENV_KWARGS, TrainConfig

#: a 1 s version of the paper's circle (100 steps per episode)
SHORT_PATH = {"type": "circle", "radius": 0.1, "tilt": 0.5236, "yaw": 3.1416, "duration": 1.0}
#: small, fast hyperparameters per algorithm (the defaults are for real runs)
TINY = {
    "sac": {
        "buffer_size": 2000,
        "learning_starts": 100,
        "batch_size": 32,
        "train_freq": 4,
        "gradient_steps": 2,
        "policy_kwargs": {"net_arch": [32, 32]},
    },
    "td3": {
        "buffer_size": 2000,
        "learning_starts": 100,
        "batch_size": 32,
        "train_freq": 4,
        "gradient_steps": 2,
        "policy_kwargs": {"net_arch": [32, 32]},
    },
    "ppo": {
        "n_steps": 128,
        "batch_size": 64,
        "n_epochs": 2,
        "policy_kwargs": {"net_arch": {"pi": [32, 32], "vf": [32, 32]}},
    },
}
#: the final evaluation's seeds in these tests (reported range, as in real runs)
FINAL_SEED = 10_000


def tiny_config(algo: str, out: Path, **changes) -> TrainConfig:
    fields = dict(
        algo=algo,
        timesteps=300,
        n_envs=2,
        seed=3,
        out=str(out),
        hyperparams=TINY[algo],
        env_kwargs={**LEARNING_ENV_KWARGS, "path": SHORT_PATH},
        eval_freq=150,
        eval_episodes=1,
        final_eval_episodes=1,
        final_eval_seed=FINAL_SEED,
        checkpoint_freq=0,
        progress_bar=False,
    )
    fields.update(changes)
    return TrainConfig(**fields)


# --- config -------------------------------------------------------------------------------------------------
def test_config_json_round_trip():
    cfg = TrainConfig(
        algo="ppo",
        timesteps=1234,
        n_envs=2,
        seed=7,
        out="x",
        dynamics="physics",
        env_kwargs={"model_error": 0.0, "error_bound": 0.2},
        hyperparams={"n_steps": 64, "policy_kwargs": {"net_arch": [8]}},
        wrappers=("pos_error",),
        obs_keys=("pos_error", "time"),
        normalize_reward=False,
        tensorboard=True,
    )
    back = TrainConfig.from_json(cfg.to_json())
    assert back == cfg
    assert isinstance(back.obs_keys, tuple) and isinstance(back.wrappers, tuple)
    assert TrainConfig.from_json(TrainConfig().to_json()) == TrainConfig()


def test_config_unknown_field_is_refused():
    with pytest.raises(ValueError, match="unknown TrainConfig field.*timestep"):
        TrainConfig.from_dict({"timestep": 10})


def test_every_algorithm_has_resolvable_defaults():
    from train import algos

    for name in ALGOS:
        algos.check_keys(name, algos.resolve(name))


@pytest.mark.parametrize(
    "changes, match",
    [
        ({"algo": "dqn"}, "unknown algorithm 'dqn'; known: sac, td3, ppo"),
        ({"env_id": "WheeledPuma-Circle-v9"}, "unknown env id.*WheeledPuma-Circle-v0"),
        ({"timesteps": 0}, "timesteps must be an integer >= 1"),
        ({"eval_seed": 10_000}, "development range"),
        ({"dynamics": "fast"}, "unknown dynamics 'fast'; accepted: physics, kinematic"),
        ({"env_kwargs": {"dynamics": "physics"}}, "--dynamics"),
        ({"env_kwargs": {"max_speed": 1}}, "unknown env argument.*max_speed.*accepted"),
        ({"wrappers": ("pos_err",)}, "unknown observation wrapper.*pos_error"),
        ({"hyperparams": {"seed": 3}}, "set by mobman-train itself"),
        ({"hyperparams": {"policy_kwargs": {"activation_fn": "swish"}}}, "unknown activation_fn 'swish'"),
        ({"hyperparams": {"learning_rate": "cos_1e-3"}}, "expected a number or 'lin_<number>'"),
    ],
)
def test_config_rejects_bad_values(changes, match):
    with pytest.raises(ValueError, match=match):
        TrainConfig(**changes)


# --- CLI: bad arguments fail before training ---------------------------------------------------------------
@pytest.mark.parametrize(
    "extra, match",
    [
        (["--timesteps", "0"], "timesteps must be an integer >= 1"),
        (["--env", "Nope-v0"], "unknown env id 'Nope-v0'"),
        (["--env-kwargs", "{bad json"], "not valid JSON"),
        (["--env-kwargs", "[1, 2]"], "must be a JSON object"),
        (["--env-kwargs", '{"model_error": -1}'], "model_error must be a finite number >= 0"),
        (["--hyperparams", "missing.yaml"], "no such file"),
        (["--hyperparams", "HP"], r"unknown hyperparameter\(s\) \['learning_rat'\] for sac; accepted: .*learning_rate"),
        (["--seed", "-1"], "seed must be an integer >= 0"),
    ],
)
def test_cli_bad_arguments_fail_before_training(tmp_path, capsys, extra, match):
    hp = tmp_path / "hp.yaml"
    hp.write_text("learning_rat: 0.001\n")
    out = tmp_path / "run"
    argv = ["--algo", "sac", "--out", str(out)] + [str(hp) if a == "HP" else a for a in extra]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "mobman-train: error:" in err
    import re

    assert re.search(match, err), err
    assert not out.exists()  # nothing started


def test_cli_unknown_algo_is_an_argparse_error(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--algo", "dqn"])
    assert exc.value.code == 2
    assert "invalid choice: 'dqn'" in capsys.readouterr().err


def test_cli_refuses_non_empty_out_and_bad_resume(tmp_path, capsys):
    out = tmp_path / "run"
    out.mkdir()
    (out / "keep.txt").write_text("x")
    assert main(["--out", str(out)]) == 2
    assert "exists and is not empty; pass --overwrite" in capsys.readouterr().err
    assert main(["--resume", str(tmp_path / "nowhere")]) == 2
    assert "is not a run folder" in capsys.readouterr().err


def test_hyperparameter_that_fails_in_sb3_is_refused_before_the_run_folder(tmp_path, capsys):
    out = tmp_path / "run"
    hp = tmp_path / "hp.json"
    hp.write_text(json.dumps({"n_steps": -1}))
    argv = [
        "--algo",
        "ppo",
        "--out",
        str(out),
        "--hyperparams",
        str(hp),
        "--env-kwargs",
        json.dumps({"path": SHORT_PATH}),
    ]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "mobman-train: error: the hyperparameters of ppo" in err and "n_steps=-1" in err, err
    assert "Traceback" not in err
    assert not out.exists()  # so a corrected rerun is not refused


def _fake_run_folder(tmp_path) -> Path:
    from train.runfolder import CONFIG_SCHEMA

    out = tmp_path / "run"
    (out / "checkpoints").mkdir(parents=True)
    cfg = TrainConfig(out=str(out), env_kwargs={**LEARNING_ENV_KWARGS, "path": SHORT_PATH})
    (out / "config.json").write_text(json.dumps({"schema": CONFIG_SCHEMA, **cfg.to_dict()}))
    entry = {"steps": 100, "model": "model_100_steps.zip", "vecnormalize": None, "replay_buffer": None}
    (out / "checkpoints" / "latest.json").write_text(json.dumps(entry))
    return out


@pytest.mark.parametrize(
    "damage, match",
    [
        ("config", r"config.json is not a readable JSON file"),
        ("config_field", r"cannot resume from .*config.json: timesteps must be an integer >= 1"),
        ("latest", r"checkpoints/latest.json is not a readable JSON file"),
        ("latest_keys", r"checkpoints/latest.json is not a checkpoint index"),
        ("checkpoint", r"names model file .*checkpoints/model_100_steps.zip, which is missing"),
        ("checkpoint_path", r"latest.json: replay_buffer must be a plain name .*got '../../elsewhere.pkl'"),
    ],
)
def test_resume_names_the_damaged_file(tmp_path, capsys, damage, match):
    import re

    out = _fake_run_folder(tmp_path)
    if damage == "config":
        (out / "config.json").write_text("{truncated")
    elif damage == "config_field":
        cfg = json.loads((out / "config.json").read_text())
        (out / "config.json").write_text(json.dumps({**cfg, "timesteps": -5}))
    elif damage == "latest":
        (out / "checkpoints" / "latest.json").write_text("[1, 2")
    elif damage == "latest_keys":
        (out / "checkpoints" / "latest.json").write_text('{"steps": 100}')
    elif damage == "checkpoint_path":
        entry = json.loads((out / "checkpoints" / "latest.json").read_text())
        (out / "checkpoints" / "latest.json").write_text(json.dumps({**entry, "replay_buffer": "../../elsewhere.pkl"}))
        (tmp_path / "elsewhere.pkl").write_bytes(b"")
    assert main(["--resume", str(out), "--timesteps", "200"]) == 2
    err = capsys.readouterr().err
    assert re.search(match, err), err
    assert ".zip.zip" not in err and "Traceback" not in err


def test_missing_stable_baselines3_names_the_extra(tmp_path):
    code = "import sys; sys.modules['stable_baselines3'] = None\nimport train.cli\nsys.exit(train.cli.main(['--out', sys.argv[1]]))"
    out = subprocess.run([sys.executable, "-c", code, str(tmp_path / "r")], capture_output=True, text=True, timeout=60)
    assert out.returncode == 2, out.stderr
    assert "mobman-train needs Stable-Baselines3 and torch" in out.stderr and 'pip install "mobman[rl]"' in out.stderr
    assert "Traceback" not in out.stderr and not (tmp_path / "r").exists()


def test_progress_bar_only_on_a_terminal(monkeypatch):
    from train.cli import build_parser, config_from_args

    parse = lambda *a: config_from_args(build_parser().parse_args(list(a)))
    assert parse().progress_bar is False  # pytest's captured stderr is not a terminal
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True, raising=False)
    assert parse().progress_bar is True
    assert parse("--no-progress").progress_bar is False and parse("--quiet").progress_bar is False


def test_hyperparams_file_per_algorithm(tmp_path):
    from train.cli import load_hyperparams

    f = tmp_path / "hp.yml"
    f.write_text("sac:\n  learning_rate: 0.001\nppo:\n  n_steps: 64\n")
    assert load_hyperparams(str(f), "ppo") == {"hyperparams": {"n_steps": 64}}
    with pytest.raises(ValueError, match="not for --algo td3"):
        load_hyperparams(str(f), "td3")


@pytest.mark.parametrize("algo, steps", [("ppo", 5_000_000), ("sac", 200_000)])
def test_the_shipped_zoo_files_are_mobman_trains_defaults(algo, steps):
    """`mobman-train --hyperparams train/hyperparams/ALGO.yml` (rl-zoo's format, keyed by env id) trains exactly
    what the defaults train: same hyperparameters, normalisation, observation, alive bonus, steps."""
    from train.cli import build_parser, config_from_args

    root = Path(__file__).resolve().parents[1]
    args = ["--algo", algo, "--hyperparams", str(root / "train" / "hyperparams" / f"{algo}.yml")]
    cfg = config_from_args(build_parser().parse_args(args))
    ref = TrainConfig(algo=algo, timesteps=steps, progress_bar=False)
    assert cfg.resolved_hyperparams == ref.resolved_hyperparams
    assert cfg.do_normalize_reward == ref.do_normalize_reward and cfg.normalize_obs == ref.normalize_obs
    assert (cfg.timesteps, cfg.obs_keys, cfg.wrappers, cfg.alive_bonus) == (
        ref.timesteps,
        ref.obs_keys,
        ref.wrappers,
        ref.alive_bonus,
    )
    # the command line wins over the file
    cfg = config_from_args(build_parser().parse_args(args + ["--timesteps", "500", "--alive-bonus", "1.5"]))
    assert (cfg.timesteps, cfg.alive_bonus) == (500, 1.5)


ZOO_ENTRY = """WheeledPuma-Circle-v0:
  n_timesteps: !!float 2e4
  policy: 'MultiInputPolicy'
  normalize: true
  env_wrapper:
    - train.wrappers.AgentObservation:
        wrappers: [pos_error]
        obs_keys: [pos_error, joint_pos]
  n_steps: 64
  policy_kwargs: "dict(net_arch=dict(pi=[16], vf=[16]), activation_fn=nn.ReLU, log_std_init=-1.5)"
"""


@pytest.mark.parametrize(
    "change, match",
    [
        (None, None),
        (("policy: 'MultiInputPolicy'", "policy: 'MlpPolicy'"), "MultiInputPolicy"),
        (("normalize: true", "normalize: \"{'norm_obs': True, 'gamma': 0.9}\""), "accepted: true, false, or a dict"),
        (("  n_steps: 64", "  n_steps: 64\n  frame_stack: 4"), r"\['frame_stack'\] have no mobman-train equivalent"),
        (("train.wrappers.AgentObservation:", "gymnasium.wrappers.TimeAwareObservation:"), "not one mobman-train"),
        (("nn.ReLU", "nn.SiLU"), "activation nn.SiLU; accepted"),
        (("nn.ReLU", "__import__('os')"), "may hold literals"),
        (
            ("WheeledPuma-Circle-v0:", "WheeledPuma-Line-v0:"),
            r"entries for \['WheeledPuma-Line-v0'\] but not for --env",
        ),
    ],
)
def test_zoo_entry_fields(tmp_path, change, match):
    from train.cli import load_hyperparams

    f = tmp_path / "ppo.yml"
    f.write_text(ZOO_ENTRY if change is None else ZOO_ENTRY.replace(*change))
    if match is not None:
        with pytest.raises(ValueError, match=match):
            load_hyperparams(str(f), "ppo", "WheeledPuma-Circle-v0")
        return
    fields = load_hyperparams(str(f), "ppo", "WheeledPuma-Circle-v0")
    assert fields == {
        "timesteps": 20_000,
        "normalize_obs": True,
        "normalize_reward": True,
        "alive_bonus": 0.0,  # no AliveBonus wrapper: rl-zoo would train without it
        "wrappers": ("pos_error",),
        "obs_keys": ("pos_error", "joint_pos"),
        "hyperparams": {
            "n_steps": 64,
            "policy_kwargs": {"net_arch": {"pi": [16], "vf": [16]}, "activation_fn": "relu", "log_std_init": -1.5},
        },
    }
    TrainConfig(algo="ppo", **fields)  # accepted as it is


# --- smoke training, reload, evaluate ---------------------------------------------------------------------
@pytest.mark.parametrize("algo", sorted(ALGOS))
def test_smoke_train_save_reload_evaluate(tmp_path, algo):
    import gymnasium as gym

    import policies
    from eval.rollout import rollout
    from train.run import run

    out = tmp_path / algo
    summary = run(tiny_config(algo, out))
    assert summary["status"] == "done" and summary["timesteps"] >= 300
    for name in (
        "model.zip",
        "vecnormalize.pkl",
        "config.json",
        "learning_curve.csv",
        "learning_curve.png",
        "final_eval.json",
        "summary.json",
        "monitor.csv",
        "checkpoints/latest.json",
    ):
        assert (out / name).is_file(), name
    cfg = json.loads((out / "config.json").read_text())
    for key in ("algo", "env_id", "env_kwargs", "obs_keys", "wrappers"):
        assert key in cfg
    assert cfg["algo"] == algo and cfg["wrappers"] == list(TrainConfig().wrappers)
    curve = (out / "learning_curve.csv").read_text().splitlines()
    assert len(curve) >= 3  # header, step 0, at least one later evaluation

    # reload exactly as mobman-eval does, evaluate one short episode with the benchmark's settings
    final = json.loads((out / "final_eval.json").read_text())
    env = gym.make("WheeledPuma-Circle-v0", dynamics="kinematic", path=SHORT_PATH)
    try:
        policy = policies.make(f"sb3:{out / 'model.zip'}", env)
        rec, arrays = rollout(env, policy, FINAL_SEED)
    finally:
        env.close()
    assert rec["status"] == "ok" and rec["n_steps"] == 100
    # the final evaluation of the run is the same number mobman-eval gets
    assert rec["rms_error_m"] == pytest.approx(final["agent"]["episodes"][0]["rms_error_m"], rel=0, abs=0)
    assert final["zero"]["median_rms_error_m"] > 0
    # the best model on the development seeds is a run folder of its own, evaluated beside the last one
    best = json.loads((out / "best" / "best.json").read_text())
    assert best["timesteps"] in [int(line.split(",")[0].split(".")[0]) for line in curve[1:]]
    assert final["best"]["spec"] == f"sb3:{out / 'best' / 'model.zip'}"


def test_in_process_agent_matches_sb3policy(tmp_path):
    """The live agent used for periodic evaluation sees exactly what SB3Policy rebuilds from the run folder."""
    import gymnasium as gym
    from stable_baselines3.common.vec_env import VecNormalize  # noqa: F401

    import policies
    from train.agent import Agent
    from train.run import run

    out = tmp_path / "sac"
    run(tiny_config("sac", out, eval_freq=0, final_eval_episodes=0))
    env = gym.make("WheeledPuma-Circle-v0", dynamics="kinematic", path=SHORT_PATH)
    try:
        loaded = policies.make(f"sb3:{out}", env)
        import pickle

        with open(out / "vecnormalize.pkl", "rb") as f:
            norm = pickle.load(f)
        cfg = json.loads((out / "config.json").read_text())
        live = Agent(loaded.model, norm, cfg["wrappers"], cfg["obs_keys"])
        obs, _ = env.reset(seed=5)
        for _ in range(20):
            a1, _ = live.predict(obs)
            a2, _ = loaded.predict(obs)
            np.testing.assert_array_equal(a1, a2)
            obs, *_ = env.step(a1)
    finally:
        env.close()


def test_same_seed_same_result(tmp_path):
    from train.run import run

    a = run(tiny_config("sac", tmp_path / "a", eval_freq=0))
    b = run(tiny_config("sac", tmp_path / "b", eval_freq=0))
    assert a["final_eval"]["agent"]["median_rms_error_m"] == b["final_eval"]["agent"]["median_rms_error_m"]


# --- resume and Ctrl-C ------------------------------------------------------------------------------------
def test_resume_continues_to_the_new_total(tmp_path):
    from train.callbacks import read_curve
    from train.run import resume, run

    out = tmp_path / "sac"
    run(tiny_config("sac", out, timesteps=200, checkpoint_freq=100, final_eval_episodes=0, eval_freq=100))
    first = json.loads((out / "checkpoints" / "latest.json").read_text())
    assert first["steps"] == 200 and first["replay_buffer"] == "replay_buffer.pkl"
    with pytest.raises(ValueError, match="already has 200 steps"):
        resume(out, timesteps=200)
    summary = resume(out, timesteps=350, progress_bar=False)
    n = summary["timesteps"]
    assert 350 <= n < 350 + TINY["sac"]["train_freq"]  # SB3 collects whole train_freq chunks
    assert json.loads((out / "checkpoints" / "latest.json").read_text())["steps"] == n
    assert json.loads((out / "config.json").read_text())["timesteps"] == 350
    steps = [int(r["timesteps"]) for r in read_curve(out / "learning_curve.csv")]
    assert steps == sorted(steps) and steps[0] == 0 and 200 in steps and steps[-1] == n
    assert len(steps) == len(set(steps))  # the resumed step was not evaluated twice


@pytest.mark.slow
def test_ctrl_c_saves_a_checkpoint_and_resume_finishes(tmp_path):
    """SIGINT to the whole process group (what a terminal's Ctrl-C does) with subprocess workers: the parent
    saves and exits with 130; --resume then finishes the run."""
    out = tmp_path / "run"
    hp = tmp_path / "hp.json"
    hp.write_text(json.dumps(TINY["td3"]))
    cmd = [
        sys.executable,
        "-m",
        "train",
        "--algo",
        "td3",
        "--timesteps",
        "100000",
        "--n-envs",
        "2",
        "--eval-freq",
        "0",
        "--final-eval-episodes",
        "0",
        "--out",
        str(out),
        "--quiet",
        "--hyperparams",
        str(hp),
        "--env-kwargs",
        json.dumps({"path": SHORT_PATH}),
    ]
    proc = subprocess.Popen(
        cmd,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        preexec_fn=terminal_sigint,
    )
    try:
        deadline = time.time() + 120
        while time.time() < deadline:  # wait until training runs (the monitor has episodes)
            mon = out / "monitor.csv"
            if mon.exists() and len(mon.read_text().splitlines()) > 6:
                break
            time.sleep(0.5)
        os.killpg(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, err
    assert "interrupted at" in err and "--resume" in err
    latest = json.loads((out / "checkpoints" / "latest.json").read_text())
    assert 0 < latest["steps"] < 100_000
    assert (out / "model.zip").is_file()
    assert main(["--resume", str(out), "--timesteps", str(latest["steps"] + 200), "--quiet"]) == 0
    assert json.loads((out / "summary.json").read_text())["status"] == "done"


def test_importing_train_loads_neither_torch_nor_sb3():
    code = (
        "import sys, train, train.cli, train.config; print('torch' in sys.modules, 'stable_baselines3' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out == ["False", "False"]


def test_failed_final_evaluation_keeps_the_model_and_exits_1(tmp_path, monkeypatch, capsys):
    import train.run

    def boom(config, out):
        raise RuntimeError("eval exploded")

    monkeypatch.setattr(train.run, "final_evaluation", boom)
    out = tmp_path / "run"
    hp = tmp_path / "hp.json"
    hp.write_text(json.dumps(TINY["ppo"]))
    code = main(
        [
            "--algo",
            "ppo",
            "--timesteps",
            "128",
            "--eval-freq",
            "0",
            "--final-eval-episodes",
            "1",
            "--out",
            str(out),
            "--quiet",
            "--hyperparams",
            str(hp),
            "--env-kwargs",
            json.dumps({"path": SHORT_PATH}),
        ]
    )
    assert code == 1
    assert "final evaluation failed" in capsys.readouterr().err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "done" and "eval exploded" in summary["final_eval_error"]
    assert (out / "model.zip").is_file()
    assert "mobman-eval run --env WheeledPuma-Circle-v0 --policy sb3:" in (out / "train.log").read_text()


def test_tensorboard_logs_or_a_clear_error(tmp_path):
    import importlib.util

    from train.run import run

    cfg = tiny_config("ppo", tmp_path / "tb", timesteps=128, eval_freq=0, final_eval_episodes=0, tensorboard=True)
    if importlib.util.find_spec("tensorboard") is None:
        with pytest.raises(ValueError, match="pip install tensorboard"):
            run(cfg)
        assert not (tmp_path / "tb").exists()
    else:
        run(cfg)
        assert list((tmp_path / "tb" / "tensorboard").rglob("events.out.tfevents.*"))
