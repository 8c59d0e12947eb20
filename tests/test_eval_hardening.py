"""Hardening of `mobman-eval` (issues 11 and 17): output folders, file modes, Ctrl-C, Ray addresses, video
names and frame rate, policies that call sys.exit, output formats, the working directory and shadowing files.

Subprocesses only where a process is the point (signals, a console script's sys.path, a shadowing file)."""

from __future__ import annotations

import json
import os
import signal
import stat
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from test_eval_helpers import ENV, SHORT, short_config, terminal_sigint

from eval import run
from eval.cli import main
from eval.errors import EvalError

ROOT = Path(__file__).resolve().parents[1]
TESTS = Path(__file__).resolve().parent
K = json.dumps({"path": {"type": "circle", "radius": 0.1, "duration": 0.2}})


def _env(**extra) -> dict:
    """The environment of a subprocess: this checkout and the tests folder importable."""
    path = os.pathsep.join([str(ROOT), str(TESTS), os.environ.get("PYTHONPATH", "")])
    return {**os.environ, "PYTHONPATH": path, "MPLBACKEND": "Agg", **extra}


# --- output folders ------------------------------------------------------------------------------------------
@pytest.fixture
def unwritable(tmp_path):
    """A folder this process cannot write into (root ignores permissions: /proc refuses everyone)."""
    return Path("/proc/mobman-test/out")


def test_unwritable_out_is_refused_before_the_first_rollout(unwritable, capsys, monkeypatch):
    import eval.execution.tasks as tasks

    monkeypatch.setattr(tasks, "rollout", lambda *a, **k: pytest.fail("an episode ran"))
    args = ["--policy", "zero", "--seeds", "3", "--dynamics", "kinematic", "--env-kwargs", K]
    assert main(["run", *args, "--out", str(unwritable)]) == 2
    err = capsys.readouterr().err
    assert f"--out '{unwritable}' is not writable" in err and "Traceback" not in err


@pytest.mark.parametrize(
    "command",
    [
        ["speed", "--steps", "10", "--policy", "zero"],
        ["paper", "--seeds", "1"],
        ["sweep", "--config", str(ROOT / "eval" / "sweep" / "examples" / "sweep.yaml")],
    ],
)
def test_unwritable_out_of_every_subcommand(unwritable, capsys, command):
    if command[0] == "sweep" and not Path(command[2]).is_file():
        command[2] = str(next((ROOT / "eval").rglob("examples/*.yaml")))
    assert main([*command, "--out", str(unwritable)]) == 2
    assert "is not writable" in capsys.readouterr().err


def test_mobman_train_refuses_an_unwritable_out(unwritable, capsys):
    pytest.importorskip("stable_baselines3")
    from train.cli import main as train_main

    assert train_main(["--out", str(unwritable), "--timesteps", "10"]) == 2
    err = capsys.readouterr().err
    assert "mobman-train: error: --out" in err and "is not writable" in err and "Traceback" not in err


def test_the_out_check_leaves_no_folder_behind(tmp_path, unwritable):
    from eval.output.files import check_out

    with pytest.raises(EvalError, match="is not writable"):
        check_out(unwritable / "a" / "b", overwrite=False)
    check_out(tmp_path / "new" / "deeper", overwrite=False)  # writable: probed, then removed again
    assert not (tmp_path / "new").exists()
    with pytest.raises(EvalError, match="exists and is not a directory"):
        (tmp_path / "file").write_text("x")
        check_out(tmp_path / "file", overwrite=True)


def test_default_out_folders_are_unique(tmp_path):
    from eval.output.files import make_out, resolve_out

    a, b = resolve_out(None, "run"), resolve_out(None, "run")
    assert a != b and a.parent == Path("runs") and a.name.startswith("run-")
    taken = tmp_path / "run-x"
    first = make_out(taken, exclusive=True)
    second = make_out(taken, exclusive=True)  # another run started in the same instant: its own folder
    assert first == taken and second == tmp_path / "run-x-2" and second.is_dir()


def test_overwrite_removes_stale_outputs_of_the_earlier_run_only(tmp_path):
    out = tmp_path / "out"
    run(short_config(tmp_path, policies=("zero",), plots=True, save_arrays="first"))
    assert (out / "episodes.npz").is_file() and list((out / "plots").glob("*.png"))
    (out / "notes.txt").write_text("mine")
    (out / "plots" / "my_figure.png").write_bytes(b"png")
    run(short_config(tmp_path, policies=("zero",), plots=False, save_arrays="none", overwrite=True))
    assert not (out / "episodes.npz").exists()
    assert sorted(p.name for p in (out / "plots").iterdir()) == ["my_figure.png"]
    assert (out / "notes.txt").read_text() == "mine"
    assert json.loads((out / "results.json").read_text())["config"]["save_arrays"] == "none"


@pytest.mark.parametrize("umask, mode", [(0o022, 0o644), (0o077, 0o600)])
def test_result_files_honour_the_umask(tmp_path, umask, mode):
    old = os.umask(umask)
    try:
        run(short_config(tmp_path, policies=("zero",), episodes=1))
    finally:
        os.umask(old)
    for name in ("results.json", "results.csv", "summary.md", "config.json", "episodes.npz"):
        assert stat.S_IMODE((tmp_path / "out" / name).stat().st_mode) == mode, name


# --- sweep journal and concurrent sweeps ---------------------------------------------------------------------
def _sweep_file(tmp_path) -> Path:
    import yaml

    f = tmp_path / "sweep.yaml"
    f.write_text(
        yaml.safe_dump(
            {
                "envs": [ENV],
                "policies": ["zero"],
                "seeds": {"start": 10000, "count": 2},
                "dynamics": ["kinematic"],
                "env_kwargs": SHORT,
            }
        )
    )
    return f


def test_a_second_sweep_on_a_locked_out_changes_nothing(tmp_path, capsys):
    from eval.output.journal import JOURNAL, Journal

    f, out = _sweep_file(tmp_path), tmp_path / "sweep"
    assert main(["sweep", "--config", str(f), "--out", str(out), "--quiet"]) == 0
    before = (out / "config.json").read_bytes()
    (out / "config.json").write_bytes(before.replace(b'"workers": 1', b'"workers": 1 '))
    marked = (out / "config.json").read_bytes()
    holder = Journal(out / JOURNAL)
    holder.open()  # another sweep is writing this folder
    try:
        assert main(["sweep", "--config", str(f), "--out", str(out), "--quiet"]) == 2
    finally:
        holder.close()
    assert "another sweep is writing" in capsys.readouterr().err
    assert (out / "config.json").read_bytes() == marked  # refused before config.json was rewritten


def test_a_journal_line_that_is_not_an_object_is_dropped_with_a_warning(tmp_path):
    from eval.output.journal import JOURNAL

    f, out = _sweep_file(tmp_path), tmp_path / "sweep"
    assert main(["sweep", "--config", str(f), "--out", str(out), "--quiet"]) == 0
    lines = (out / JOURNAL).read_text().splitlines()
    (out / JOURNAL).write_text("\n".join(["[1, 2]", lines[0], "42"]) + "\n")
    with pytest.warns(UserWarning) as caught:
        assert main(["sweep", "--config", str(f), "--out", str(out), "--quiet"]) == 0
    texts = [str(w.message) for w in caught]
    assert any("line 1 is list, not an episode record" in t for t in texts)
    assert any("line 3 is int, not an episode record" in t for t in texts)
    recs = [json.loads(x) for x in (out / JOURNAL).read_text().splitlines()]
    assert sum(isinstance(r, dict) for r in recs) == 2  # the dropped episode ran again


# --- Ctrl-C -------------------------------------------------------------------------------------------------
def _interrupt(
    cmd: list[str], marks: Path, n_marks: int, cwd: Path, sig: int = signal.SIGINT, group: bool = True
) -> tuple[subprocess.Popen, str, float]:
    """Start `cmd` in its own process group, send `sig` to the group (or, `group=False`, to the command's process
    only, as `timeout` and `docker stop` do) once `n_marks` episodes finished; returns the process, its stderr
    and the seconds from the signal to exit."""
    proc = subprocess.Popen(
        cmd,
        cwd=cwd,
        env=_env(MOBMAN_TEST_MARKS=str(marks)),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        preexec_fn=terminal_sigint,
    )
    try:
        deadline = time.time() + 120
        while len(list(marks.iterdir())) < n_marks and time.time() < deadline and proc.poll() is None:
            time.sleep(0.05)
        assert proc.poll() is None, proc.communicate()
        # a mark is touched at an episode's last predict, before its last step and before the worker sends the
        # record: give the marked episodes time to reach the parent, so "n finished" means delivered
        time.sleep(0.5)
        t0 = time.time()
        if group:
            os.killpg(proc.pid, sig)
        else:
            os.kill(proc.pid, sig)
        _, err = proc.communicate(timeout=60)
        return proc, err, time.time() - t0
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)


def _workers_gone(pgid: int) -> bool:
    """No worker process (multiprocessing's `spawn_main`) of the process group `pgid` is alive (the resource
    tracker, which exits by itself once the parent's pipe closes, is not a worker)."""
    for stat_file in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat_file.read_text().rsplit(")", 1)[1].split()
            cmdline = (stat_file.parent / "cmdline").read_bytes()
        except OSError:
            continue
        if int(fields[2]) == pgid and fields[0] != "Z" and b"spawn_main" in cmdline:
            return False
    return True


def _group_gone(pgid: int, tries: int = 50) -> bool:
    for _ in range(tries):
        try:
            os.killpg(pgid, 0)
        except ProcessLookupError:
            return True
        time.sleep(0.1)
    return False


@pytest.mark.slow
@pytest.mark.parametrize("workers", [1, 2])
def test_ctrl_c_keeps_the_finished_episodes_and_stops_the_workers(tmp_path, workers):
    marks, out = tmp_path / "marks", tmp_path / "out"
    marks.mkdir()
    cmd = [sys.executable, "-m", "eval", "run", "--policy", "test_eval_helpers:SlowMarked", "--seeds", "40"]
    cmd += ["--dynamics", "kinematic", "--env-kwargs", json.dumps(SHORT), "--workers", str(workers)]
    cmd += ["--out", str(out), "--no-plots"]
    proc, err, took = _interrupt(cmd, marks, 3, tmp_path)
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err
    assert "interrupted:" in err and f"results written to {out}" in err
    results = json.loads((out / "results.json").read_text())
    status = [r["status"] for r in results["episodes"]]
    assert status.count("ok") >= 3 and status.count("interrupted") >= 1 and set(status) <= {"ok", "interrupted"}
    assert results["aggregate"][0]["n"] == status.count("ok")  # the aggregate holds the finished ones
    assert _group_gone(proc.pid)  # no worker left running
    assert took < 15, f"{took:.1f} s from SIGINT to exit"
    print(f"workers={workers}: {took:.2f} s from SIGINT to exit, {status.count('ok')} of 40 episodes kept")


@pytest.mark.slow
def test_ctrl_c_of_a_sweep_exits_130_without_tracebacks(tmp_path):
    import yaml

    marks, out = tmp_path / "marks", tmp_path / "sweep"
    marks.mkdir()
    f = tmp_path / "s.yaml"
    f.write_text(
        yaml.safe_dump(
            {
                "envs": [ENV],
                "policies": ["test_eval_helpers:SlowMarked"],
                "seeds": {"start": 10000, "count": 40},
                "dynamics": ["kinematic"],
                "env_kwargs": SHORT,
            }
        )
    )
    cmd = [sys.executable, "-m", "eval", "sweep", "--config", str(f), "--out", str(out), "--workers", "2"]
    proc, err, took = _interrupt(cmd, marks, 3, tmp_path)
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "sweep interrupted" in err
    assert len((out / "episodes.jsonl").read_text().splitlines()) >= 3
    assert _group_gone(proc.pid)


def _slow_sweep_file(tmp_path: Path) -> Path:
    import yaml

    f = tmp_path / "s.yaml"
    spec = {
        "envs": [ENV],
        "policies": ["test_eval_helpers:SlowMarked"],
        "seeds": {"start": 10000, "count": 40},
        "dynamics": ["kinematic"],
        "env_kwargs": SHORT,
    }
    f.write_text(yaml.safe_dump(spec))
    return f


@pytest.mark.slow
@pytest.mark.parametrize("group", [False, True], ids=["process", "group"])
@pytest.mark.parametrize("command", ["run", "sweep", "bench"])
def test_sigterm_keeps_the_finished_episodes_and_stops_the_workers_at_once(tmp_path, command, group):
    """SIGTERM (`timeout` and `docker stop` signal the process, Slurm the whole job) stops run, sweep and bench
    as Ctrl-C does: exit 130, no traceback, the finished episodes kept, no worker left behind."""
    marks, out = tmp_path / "marks", tmp_path / "out"
    marks.mkdir()
    slow = "test_eval_helpers:SlowMarked"
    common = ["--out", str(out), "--workers", "2", "--no-plots"]
    cmd = [sys.executable, "-m", "eval", command]
    if command == "run":
        cmd += ["--policy", slow, "--seeds", "40", "--dynamics", "kinematic", "--env-kwargs", json.dumps(SHORT)]
    elif command == "sweep":
        cmd += ["--config", str(_slow_sweep_file(tmp_path))]
    else:
        cmd += ["--policy", slow, "--tasks", "circle", "--conditions", "default", "--seeds", "40", "--quiet"]
        cmd += ["--env-kwargs", json.dumps(SHORT)]
    proc, err, took = _interrupt(cmd + common, marks, 3, tmp_path, signal.SIGTERM, group)
    gone = _workers_gone(proc.pid)  # at the exit: the parent stopped its workers itself
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "KeyboardInterrupt" not in err and "interrupted" in err, err
    if command == "run":
        status = [r["status"] for r in json.loads((out / "results.json").read_text())["episodes"]]
        assert status.count("ok") >= 3 and "interrupted" in status
    else:
        kept = list(out.rglob("episodes.jsonl"))
        assert sum(len(p.read_text().splitlines()) for p in kept) >= 3, kept
    assert gone, "worker processes outlived the command"
    assert took < 15, f"{took:.1f} s from SIGTERM to exit"


# --- Ray addresses ----------------------------------------------------------------------------------------
def test_an_unreachable_ray_address_fails_at_once(tmp_path, capsys):
    pytest.importorskip("ray")
    import socket

    with socket.socket() as s:  # a loopback port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    t0 = time.perf_counter()
    rc = main(["run", "--policy", "zero", "--backend", "ray", "--address", f"127.0.0.1:{port}", "--seeds", "1"])
    took = time.perf_counter() - t0
    err = capsys.readouterr().err
    assert rc == 2 and f"cannot reach the Ray cluster at --address '127.0.0.1:{port}'" in err, err
    assert took < 30, took  # Ray's own retries take minutes


def test_a_run_connects_to_no_port_it_cannot_reach_and_parses_the_address():
    from eval.execution.ray_backend import check_address

    check_address(None)
    check_address("auto")
    with pytest.raises(EvalError, match="is not HOST:PORT"):
        check_address("localhost")


# --- policies that call sys.exit ------------------------------------------------------------------------------
def test_system_exit_in_a_constructor_names_it(tmp_path, capsys):
    assert main(["run", "--policy", "test_eval_helpers:ExitInConstructor", "--out", str(tmp_path / "o")]) == 2
    assert "SystemExit(3) raised while building it" in capsys.readouterr().err


@pytest.mark.parametrize("workers", [1, 2])
def test_system_exit_in_predict_is_a_failed_episode_with_its_traceback(tmp_path, workers):
    result = run(short_config(tmp_path, policies=("test_eval_helpers:ExitInPredict", "zero"), workers=workers))
    by = {(r["policy"], r["seed"]): r for r in result.episodes}
    for seed in (10_000, 10_001):
        rec = by[("test_eval_helpers:ExitInPredict", seed)]
        assert rec["status"] == "failed" and "SystemExit: 4" in rec["error"] and rec["n_steps"] == 2
        assert by[("zero", seed)]["status"] == "ok"


# --- video ------------------------------------------------------------------------------------------------
def test_video_names_differ_for_specs_with_dots(tmp_path):
    from eval.output.video import encode, video_name

    names = {video_name(ENV, "kinematic", f"nnbc:gamma={g}", 10_000) for g in (0.5, 0.7)}
    assert names == {f"{ENV}_kinematic_nnbc-gamma=0.5_seed10000", f"{ENV}_kinematic_nnbc-gamma=0.7_seed10000"}
    frames = [np.full((16, 16, 3), 40 * i, np.uint8) for i in range(3)]
    paths = {encode(frames, tmp_path / n, 25.0) for n in names}
    assert len(paths) == 2 and all(p.name.startswith(f"{ENV}_kinematic_nnbc-gamma=0.") for p in paths)
    assert {p.name.split("=")[1][:3] for p in paths} == {"0.5", "0.7"}


def _timing(path: Path) -> tuple[float, float]:
    """(frame rate, playing time in s) read back from a video file. GIF: Pillow merges identical consecutive
    frames into one longer one, so the rate is that of the shortest frame and the time the sum of all."""
    if path.suffix == ".gif":
        from PIL import Image, ImageSequence

        with Image.open(path) as im:
            durations = [frame.info["duration"] for frame in ImageSequence.Iterator(im)]
        return 1000.0 / min(durations), sum(durations) / 1000.0
    import imageio.v2 as imageio

    with imageio.get_reader(path) as r:
        fps = float(r.get_meta_data()["fps"])
        return fps, r.count_frames() / fps


@pytest.mark.parametrize("render_fps", [25, 100])
def test_video_plays_in_real_time(tmp_path, monkeypatch, render_fps):
    """Frames every control_freq / fps steps, written at that rate: the video lasts as long as the episode,
    also when the env renders at its control rate (100 Hz)."""
    from mobman_env.env import WheeledPumaEnv

    monkeypatch.setitem(WheeledPumaEnv.metadata, "render_fps", render_fps)
    duration = 0.4
    cfg = short_config(
        tmp_path,
        policies=("zero",),
        episodes=1,
        video=True,
        env_kwargs={"path": {"type": "circle", "duration": duration}},
    )
    (video,) = (run(cfg).out / "videos").iterdir()
    fps, seconds = _timing(video)
    assert fps == pytest.approx(25.0)
    assert seconds == pytest.approx(duration, abs=1.5 / fps)


def test_video_without_imageio_falls_back_to_a_gif(tmp_path):
    code = (
        "import sys\n"
        "for m in ('imageio', 'imageio.v2', 'imageio_ffmpeg'): sys.modules[m] = None\n"
        "import importlib.util as u; real = u.find_spec\n"
        "u.find_spec = lambda n, *a: None if n.split('.')[0] in ('imageio', 'imageio_ffmpeg') else real(n, *a)\n"
        "from eval.cli import main\n"
        f"sys.exit(main(['run', '--policy', 'random', '--episodes', '1', '--dynamics', 'kinematic', '--env-kwargs', "
        f"{json.dumps(json.dumps({'path': {'type': 'circle', 'duration': 0.2}}))}, '--video', '--quiet', "
        f"'--no-plots', '--out', {str(tmp_path / 'o')!r}]))\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], env=_env(), capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    (video,) = (tmp_path / "o" / "videos").iterdir()
    fps, seconds = _timing(video)
    assert video.suffix == ".gif" and fps == pytest.approx(25.0) and seconds == pytest.approx(0.2, abs=0.06)


# --- stdout formats ----------------------------------------------------------------------------------------
def test_the_console_table_is_whole_through_a_pipe(tmp_path):
    """stdout a pipe (a log file, `| tee`): rich would assume 80 columns and drop the timing column; every
    column and the whole policy spec are printed."""
    spec = "nnbc-plus:task_dither=0.001,probe_speed=0.04"
    args = ["run", "--policy", spec, "--policy", "zero", "--seeds", "1", "--dynamics", "kinematic"]
    proc = subprocess.run(
        [sys.executable, "-m", "eval", *args, "--env-kwargs", K, "--no-plots", "--out", str(tmp_path / "o")],
        env={k: v for k, v in _env().items() if k != "COLUMNS"},
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    header = next(line for line in proc.stdout.splitlines() if "policy" in line)
    assert header.split()[-1] == "µs", proc.stdout  # the timing column, last, is there
    assert any(line.split()[:1] == [spec] and line.split()[-1].isdigit() for line in proc.stdout.splitlines())


@pytest.mark.parametrize("fmt, file", [("json", "results.json"), ("csv", "results.csv"), ("markdown", "summary.md")])
def test_format_prints_the_file_on_stdout(tmp_path, capsys, fmt, file):
    out = tmp_path / fmt
    args = ["run", "--policy", "zero", "--seeds", "1", "--dynamics", "kinematic", "--env-kwargs", K]
    assert main([*args, "--no-plots", "--format", fmt, "--out", str(out)]) == 0
    captured = capsys.readouterr()
    assert captured.out == (out / file).read_text()
    assert f"results in {out}" in captured.err
    if fmt == "json":
        assert json.loads(captured.out)["episodes"][0]["policy"] == "zero"


# --- the working directory and shadowing files --------------------------------------------------------------
CONSOLE_SCRIPT = (
    "import os, sys\n"
    "sys.path = [p for p in sys.path if p not in ('', os.getcwd())]  # as a console script: no cwd on sys.path\n"
    "from eval.cli import main\n"
    "sys.exit(main(sys.argv[1:]))\n"
)


@pytest.mark.parametrize("workers", ["1", "2"])
def test_module_attr_from_the_working_directory_as_the_console_script(tmp_path, workers):
    """A console script imports `mymod` of `--policy mymod:MyCtrl` from the working directory (in its workers
    too), and nothing else from there: a planted defusedxml.py or dill.py (modules libraries try optionally) is
    never imported."""
    (tmp_path / "mymod.py").write_text(
        "import numpy as np\n"
        "class MyCtrl:\n"
        "    def reset(self, obs, info=None, *, seed=None): pass\n"
        "    def predict(self, observation, state=None, episode_start=None, deterministic=True):\n"
        "        return np.zeros(8, dtype=np.float32), state\n"
    )
    for name in ("defusedxml", "dill"):
        (tmp_path / f"{name}.py").write_text(f"open({str(tmp_path / (name + '-ran'))!r}, 'w').close()\n")
    args = ["run", "--policy", "mymod:MyCtrl", "--policy", "zero", "--seeds", "2", "--dynamics", "kinematic"]
    proc = subprocess.run(
        [sys.executable, "-c", CONSOLE_SCRIPT, *args, "--env-kwargs", K, "--quiet", "--out", "o", "--workers", workers],
        cwd=tmp_path,
        env=_env(),
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    assert {e["status"] for e in json.loads((tmp_path / "o" / "results.json").read_text())["episodes"]} == {"ok"}
    assert list((tmp_path / "o" / "plots").iterdir())  # the plots ran (matplotlib and PIL import optionally)
    assert not list(tmp_path.glob("*-ran")), "a planted module of the working directory was imported"


def test_a_file_name_as_module_is_refused_with_the_fix(tmp_path, capsys):
    (tmp_path / "mypol.py").write_text("class Pol: pass\n")
    assert main(["run", "--policy", "mypol.py:Pol", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "'mypol.py' is a file name; name the module, without .py: mypol:Pol" in err and "Traceback" not in err


def test_a_module_that_does_not_import_shows_why(tmp_path, capsys):
    assert main(["run", "--policy", "nosuchmodule_xyz:Ctrl", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "No module named 'nosuchmodule_xyz'" in err and "working directory or on PYTHONPATH" in err


def test_a_shadowing_train_py_does_not_hide_the_shipped_agent(tmp_path):
    pytest.importorskip("stable_baselines3")
    (tmp_path / "train.py").write_text("raise RuntimeError('the user train.py was imported')\n")
    script = tmp_path / "script.py"
    script.write_text(
        "import gymnasium as gym, policies\n"
        "env = gym.make('WheeledPuma-Circle-v0', dynamics='kinematic')\n"
        "p = policies.make('sb3:sac-circle', env)\n"
        "obs, _ = env.reset(seed=10000)\n"
        "print(p.predict(obs)[0].shape)\n"
    )
    proc = subprocess.run(
        [sys.executable, str(script)], cwd=tmp_path, env=_env(), capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip().endswith("(8,)")


def test_a_shadowing_policies_py_is_named_by_the_cli(tmp_path):
    (tmp_path / "policies.py").write_text("# the user's own notes on policies\n")
    proc = subprocess.run(
        [sys.executable, "-m", "eval", "run", "--policy", "zero", "--out", "o"],
        cwd=tmp_path,
        env=_env(),
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2, proc.stderr
    assert f"`import policies` found {tmp_path / 'policies.py'}" in proc.stderr
    assert "rename it" in proc.stderr and "Traceback" not in proc.stderr


def test_a_shadowing_eval_py_is_named_when_train_is_imported(tmp_path):
    pytest.importorskip("stable_baselines3")
    (tmp_path / "eval.py").write_text("# the user's own evaluation script\n")
    code = "import sys; from train.cli import main; sys.exit(main(['--out', 'r', '--timesteps', '10']))"
    proc = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=_env(), capture_output=True, text=True)
    assert proc.returncode != 0 and not (tmp_path / "r").exists()
    assert f"ImportError: `import eval` found {tmp_path / 'eval.py'}, not mobman's eval package" in proc.stderr


def test_format_json_through_a_pipe_is_only_json(tmp_path):
    """A real command line: stdout holds the JSON alone (native libraries' output goes to stderr)."""
    out = tmp_path / "o"
    cmd = [sys.executable, "-m", "eval", "run", "--policy", "zero", "--seeds", "1", "--dynamics", "kinematic"]
    cmd += ["--env-kwargs", K, "--no-plots", "--format", "json", "--out", str(out)]
    proc = subprocess.run(cmd, env=_env(), capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout) == json.loads((out / "results.json").read_text())
    assert f"results in {out}" in proc.stderr


# --- a full disk ------------------------------------------------------------------------------------------------
class _Disk:
    """Fault injection: the disk fills after `free` more journal lines (`os.write` of eval.output.journal), or
    at the atomic write of a file named `full_at` (`os.replace` of eval.output.files): ENOSPC, as a full disk
    gives."""

    def __init__(self, monkeypatch, free: int | None = None, full_at: str | None = None):
        import errno

        import eval.output.files as files
        import eval.output.journal as journal

        self.free, self.full_at = free, full_at
        real_write, real_replace = os.write, os.replace

        def write(fd, data):
            if self.free is not None and self.free <= 0:
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            if self.free is not None:
                self.free -= 1
            return real_write(fd, data)

        def replace(src, dst):
            if self.full_at is not None and Path(dst).name == self.full_at:
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            return real_replace(src, dst)

        monkeypatch.setattr(journal.os, "write", write)
        monkeypatch.setattr(files.os, "replace", replace)


RUN4 = ["run", "--policy", "zero", "--seeds", "4", "--dynamics", "kinematic", "--env-kwargs", K, "--no-plots"]


@pytest.mark.parametrize("batch_size", ["1", "64"])
def test_a_full_disk_while_journaling_stops_the_run_with_exit_2_and_keeps_what_was_journaled(
    tmp_path, capsys, monkeypatch, batch_size
):
    out = tmp_path / "out"
    _Disk(monkeypatch, free=2)
    assert main([*RUN4, "--out", str(out), "--batch-size", batch_size, "--quiet"]) == 2
    err = capsys.readouterr().err
    assert f"cannot write {out / 'episodes.jsonl'} (No space left on device); free space and resume" in err, err
    assert "Traceback" not in err
    lines = (out / "episodes.jsonl").read_text().splitlines()
    assert len(lines) == 2 and all(json.loads(x)["status"] == "ok" for x in lines)


def _named_command(err: str) -> list[str]:
    """The argv of the command a message names ("the command that resumes: mobman-eval ..."), for `main`."""
    import shlex

    line = err.split("the command that resumes: ", 1)[1].splitlines()[0]
    argv = shlex.split(line)
    assert argv[0] == "mobman-eval"
    return argv[1:]


@pytest.mark.parametrize("full_at", [None, "results.json"])
def test_after_a_full_disk_the_command_the_message_names_finishes_the_run_without_rerunning_the_journaled(
    tmp_path, capsys, monkeypatch, full_at
):
    """The disk fills while journaling (2 of 4 episodes kept) or at the report (all 4 journaled): the message
    names the exact command that resumes; it finishes with every episode, the journaled ones kept as they were
    (not run again: the journal gains only the missing episodes' lines)."""
    out = tmp_path / "out"
    _Disk(monkeypatch, free=None if full_at else 2, full_at=full_at)
    assert main([*RUN4, "--out", str(out), "--batch-size", "1", "--quiet", "--overwrite"]) == 2
    err = capsys.readouterr().err
    assert "free space and resume: the same command with --out" in err and "Traceback" not in err, err
    argv = _named_command(err)
    assert "--resume" in argv and "--overwrite" not in argv
    before = [json.loads(x) for x in (out / "episodes.jsonl").read_text().splitlines()]
    monkeypatch.undo()  # the disk has room again
    assert main(argv) == 0, capsys.readouterr().err
    after = [json.loads(x) for x in (out / "episodes.jsonl").read_text().splitlines()]
    assert after[: len(before)] == before
    assert sorted(r["seed"] for r in after) == list(range(10_000, 10_004))  # each episode journaled once
    res = json.loads((out / "results.json").read_text())
    assert [e["seed"] for e in res["episodes"]] == list(range(10_000, 10_004))
    assert all(e["status"] == "ok" for e in res["episodes"])
    kept = {r["seed"]: r["wall_s"] for r in before}
    assert all(e["wall_s"] == kept[e["seed"]] for e in res["episodes"] if e["seed"] in kept)


def test_resume_refuses_a_folder_without_a_run_or_with_other_settings(tmp_path, capsys):
    out = tmp_path / "out"
    assert main([*RUN4, "--out", str(out), "--quiet", "--resume"]) == 2
    assert f"--out '{out}' holds no run to resume (no episodes.jsonl); drop --resume" in capsys.readouterr().err
    assert main([*RUN4, "--out", str(out), "--quiet", "--resume", "--overwrite"]) == 2
    assert "--resume keeps the episodes in --out, --overwrite starts over" in capsys.readouterr().err
    assert main([*RUN4, "--out", str(out), "--quiet"]) == 0
    assert main([*RUN4, "--out", str(out), "--quiet", "--resume", "--tolerance", "0.01"]) == 2
    assert "holds a run with other settings (tolerance: 0.006 there, 0.01 now)" in capsys.readouterr().err


def test_a_full_disk_at_the_report_exits_2_naming_the_file_and_the_journal(tmp_path, capsys, monkeypatch):
    out = tmp_path / "out"
    _Disk(monkeypatch, full_at="results.json")
    assert main([*RUN4, "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert f"cannot write {out / 'results.json'} (No space left on device); free space and resume" in err, err
    assert f"(the 4 finished episodes are in {out / 'episodes.jsonl'})" in err and "Traceback" not in err
    assert [json.loads(x)["seed"] for x in (out / "episodes.jsonl").read_text().splitlines()] == list(
        range(10_000, 10_004)
    )
    assert not list(out.glob(".results.json.*.tmp"))  # no temporary file left behind


def test_the_journal_of_a_run_is_kept_beside_its_results(tmp_path):
    result = run(short_config(tmp_path, episodes=3))
    lines = [json.loads(x) for x in (result.out / "episodes.jsonl").read_text().splitlines()]
    assert [r["seed"] for r in lines] == [e["seed"] for e in result.episodes]
    assert [r["max_error_m"] for r in lines] == [e["max_error_m"] for e in result.episodes]


@pytest.mark.parametrize(
    "argv, expected",
    [
        (["run", "--policy", "zero"], "mobman-eval run --policy zero --out 'runs/a b' --resume"),
        (["run", "--out", "x", "--overwrite", "--quiet"], "mobman-eval run --quiet --out 'runs/a b' --resume"),
        (["run", "--out=x", "--resume", "--seeds", "4"], "mobman-eval run --seeds 4 --out 'runs/a b' --resume"),
    ],
)
def test_the_resume_command_replaces_out_and_drops_overwrite(argv, expected):
    from eval.cli import resume_command

    assert resume_command(argv, ("--out", "runs/a b", "--resume")) == expected
