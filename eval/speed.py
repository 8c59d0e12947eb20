"""The speed benchmark: `mobman-eval speed` (`SpeedConfig`, `measure`; measures, asserts nothing).

What it measures, all in the same run so that the ratios compare like with like on a shared machine:

| figure | how |
|---|---|
| env steps/s (kinematic, physics) | `env.step` of `gym.make("WheeledPuma-Circle-v0", dynamics=...)` (with Gymnasium's wrappers) under small random actions, resets not timed |
| bare PyBullet steps/s | the same robot in the same client (`env.unwrapped.sim.client`) from the same start under the same commands: one `setJointMotorControlArray` and `n_substeps` x `stepSimulation()` per control step, nothing else (stepping cost depends on the motion, so an idle robot is no fair baseline) |
| ratio | env steps/s / bare steps/s at the same substeps |
| physics at 2, 4, 10 substeps | env and bare steps/s at each |
| predict microseconds | the whole `predict` call of each built-in policy over one kinematic episode (median, p99) |
| episodes/s | `eval.run` of 20 s kinematic `nnbc` episodes with `workers` 1 and 2, one episode at a time (`batch_size` 1) and batched (`EvalConfig`'s default `batch_size`: `eval.execution.batches`), worker start-up included |
| vector env robot-steps/s | `gym.make_vec(..., vectorization_mode="vector_entry_point", dynamics="kinematic")` at N = 1, 64, 1024 (`mobman_env.vector`), random actions, no autoreset inside the timed block |
| batched predict | the whole batched `predict` of `policies.make(spec, vector_env)` at N = 64, per robot-step |
| batched episodes/s | `eval.rollout.rollout_batch` of `--batch-size` 20 s kinematic `nnbc` and `clik` episodes in one process (one vector env, one batched policy) |
| paper, kinematic half (`--paper`) | CPU seconds of `mobman-eval paper --dynamics kinematic --workers 1` in this process (its 7 controllers x 20 reported seeds, batched, with its figures and files) |
| peers (`--peers`) | steps/s of panda-gym `PandaReach-v3` and MuJoCo `Reacher-v5` (installed with the `[bench]` extra), timed interleaved with the kinematic env in the same process; ratios mobman / peer |

Timed blocks in this process count its CPU time (`CLOCK`: per CPU-second, so other jobs on a shared machine
change the figures less); the `eval.run` episodes/s and the predict table are wall time. Each timed block is repeated (`--repeats`, interleaving env and bare runs) and the best repeat is reported: on
a machine shared with other jobs the best repeat is the least disturbed one. The load average at the start is
recorded beside the figures. Writes `speed.json` and `speed.md` (its figures as Markdown, the source of the
blocks of docs/performance.md) into `--out` and prints a table.
"""

from __future__ import annotations

import os
import platform
import tempfile
import time
from dataclasses import dataclass
from datetime import datetime, timezone
from typing import Any

import numpy as np

SPEED_ENV = "WheeledPuma-Circle-v0"
SUBSTEPS = (2, 4, 10)
WORKERS = (1, 2)
#: `EvalConfig.batch_size` of the `eval.run` episodes/s rows: the single path, and the default (batched)
EVAL_BATCH_SIZES = (1, None)
#: the clock of every block run in this process: its CPU time. On a machine shared with other jobs the wall time
#: mostly measures them (at a load average of 10 on 2 cores a process gets a fifth of a core); the `eval.run`
#: episodes/s (worker processes) and the predict times inside the rollout loop stay wall time
CLOCK = time.process_time
VECTOR_SIZES = (1, 64, 1024)
#: robots of the batched-predict block
PREDICT_BATCH = 64
#: (label, id, module to import first) of the peers `--peers` races
PEERS = (("panda-gym", "PandaReach-v3", "panda_gym"), ("MuJoCo", "Reacher-v5", None))


# --- timed blocks ----------------------------------------------------------------------------------------


def _env(dynamics: str, n_substeps: int = 2):
    from eval.rollout import make_env

    return make_env(SPEED_ENV, dynamics, env_kwargs={"n_substeps": n_substeps} if dynamics == "physics" else {})


def time_env_steps(env, actions: np.ndarray) -> float:
    """Seconds for `len(actions)` env steps (resets at episode ends are not timed)."""
    total = 0.0
    i = 0
    n = len(actions)
    clock = CLOCK
    while i < n:
        t0 = clock()
        while i < n:
            _, _, term, trunc, _ = env.step(actions[i])
            i += 1
            if term or trunc:
                break
        total += clock() - t0
        if i < n:
            env.reset()
    return total


def time_bare_steps(sim, actions: np.ndarray, action_scale: np.ndarray, n_substeps: int) -> float:
    """Seconds for `len(actions)` bare control steps on the sim's client: the same velocity-motor command
    (`setJointMotorControlArray`, torque limits of the robot) and `n_substeps` x `stepSimulation()`, with no
    state read back, no limit check and no observation: the least any env on this robot must do per step."""
    import pybullet

    client, body, ids = sim.client, sim.body, sim.act_ids
    forces = sim.torque_limits
    targets = (actions.astype(float) * action_scale).tolist()
    control, step, mode = client.setJointMotorControlArray, client.stepSimulation, pybullet.VELOCITY_CONTROL
    t0 = CLOCK()
    for u in targets:
        control(body, ids, mode, targetVelocities=u, forces=forces)
        for _ in range(n_substeps):
            step()
    return CLOCK() - t0


def env_vs_bare(dynamics: str, n_substeps: int, steps: int, repeats: int, seed: int = 0) -> dict:
    """Best-of-`repeats` env steps/s and bare PyBullet steps/s of the same robot at the same substeps.

    For the kinematic env the bare figure is taken from a physics env's client at `n_substeps` (the kinematic
    env makes no PyBullet call per step, so it has no bare counterpart of its own)."""
    env = _env(dynamics, n_substeps)
    phys = env if dynamics == "physics" else _env("physics", n_substeps)
    rng = np.random.default_rng(seed)
    actions = rng.uniform(-0.2, 0.2, size=(steps, 8)).astype(np.float32)
    env_t, bare_t = [], []
    try:
        env.reset(seed=seed)
        if phys is not env:
            phys.reset(seed=seed)
        sim = phys.unwrapped.sim
        scale = np.asarray(phys.unwrapped.action_scale, float)
        for _ in range(repeats):
            env_t.append(time_env_steps(env, actions))
            phys.reset(seed=seed)  # the same robot from the same start, under the same commands
            bare_t.append(time_bare_steps(sim, actions, scale, n_substeps))
            env.reset(seed=seed)
    finally:
        env.close()
        if phys is not env:
            phys.close()
    env_sps, bare_sps = steps / min(env_t), steps / min(bare_t)
    return {
        "dynamics": dynamics,
        "n_substeps": n_substeps,
        "steps": steps,
        "env_steps_per_s": env_sps,
        "bare_steps_per_s": bare_sps,
        "ratio_env_to_bare": env_sps / bare_sps,
        "env_steps_per_s_all": [steps / t for t in env_t],
        "bare_steps_per_s_all": [steps / t for t in bare_t],
    }


def check_policies(specs: list[str] | None) -> None:
    """Build every spec once on a kinematic env, so an unknown or broken policy stops the benchmark before it
    starts (`EvalError`) instead of being skipped at the end."""
    from eval.rollout import make_policy

    if not specs:
        return
    env = _env("kinematic")
    try:
        for spec in specs:
            make_policy(spec, env, 0)
    finally:
        env.close()


def predict_times(specs: list[str], seed: int = 0) -> list[dict]:
    """Median and p99 of the whole predict call of each policy over one kinematic episode (the eval loop)."""
    from eval.rollout import make_policy, rollout

    rows: list[dict[str, Any]] = []
    env = _env("kinematic")
    try:
        for spec in specs:
            try:
                policy = make_policy(spec, env, seed)
            except Exception as exc:
                rows.append({"policy": spec, "status": f"skipped: {exc}"})
                continue
            rec, arrays = rollout(env, policy, seed)
            if rec["status"] != "ok":
                rows.append({"policy": spec, "status": "failed: " + rec["error"].strip().splitlines()[-1]})
                continue
            assert arrays is not None  # an episode that ran has its arrays
            rows.append(
                {
                    "policy": spec,
                    "status": "ok",
                    "calls": int(len(arrays["predict_us"])),
                    "predict_us_median": rec["predict_us_median"],
                    "predict_us_p99": rec["predict_us_p99"],
                }
            )
    finally:
        env.close()
    return rows


def episodes_per_second(
    workers: int, episodes: int, policy: str = "nnbc", seed: int = 0, batch_size: int | None = None
) -> dict:
    """Episodes/s of `eval.run` (wall time of its execution) with `workers` and `batch_size` (None: the
    `EvalConfig` default)."""
    from eval.config import EvalConfig
    from eval.runner import run

    if batch_size is None:
        batch_size = EvalConfig.batch_size

    with tempfile.TemporaryDirectory(prefix="mobman-speed-") as tmp:
        cfg = EvalConfig(
            envs=(SPEED_ENV,),
            policies=(policy,),
            episodes=episodes,
            seed=seed,
            out=tmp,
            overwrite=True,
            workers=workers,
            batch_size=batch_size,
            dynamics=("kinematic",),
            plots=False,
            save_arrays="none",
            progress=False,
            command="speed",
        )
        t0 = time.perf_counter()
        result = run(cfg)
        total = time.perf_counter() - t0
    pids = {r["pid"] for r in result.episodes}
    steps = sum(r.get("n_steps") or 0 for r in result.episodes)
    return {
        "workers": workers,
        "batch_size": batch_size,
        "episodes": episodes,
        "policy": policy,
        "dynamics": "kinematic",
        "episodes_per_s": episodes / result.results["wall_s"],
        "env_steps_per_s": steps / result.results["wall_s"],
        "run_wall_s": result.results["wall_s"],
        "total_wall_s": total,
        "processes": len(pids),
        "episode_wall_s_median": float(np.median([r["wall_s"] for r in result.episodes])),
    }


def _vector_env(n: int):
    import gymnasium as gym

    import mobman_env  # noqa: F401  (registers the ids)

    return gym.make_vec(SPEED_ENV, num_envs=n, vectorization_mode="vector_entry_point", dynamics="kinematic")


def vector_steps(n: int, steps: int, repeats: int, seed: int = 0) -> dict:
    """Best-of-`repeats` robot-steps/s of the native vector env at N = n (at most 1,999 steps per block, so that
    no episode ends inside it, and at most about 200,000 robot-steps)."""
    steps = max(1, min(steps, 1999, 200_000 // n))
    venv = _vector_env(n)
    rng = np.random.default_rng(seed)
    actions = rng.uniform(-0.2, 0.2, size=(steps, n, 8)).astype(np.float32)
    times = []
    try:
        for _ in range(repeats):
            venv.reset(seed=seed)
            t0 = CLOCK()
            for a in actions:
                venv.step(a)
            times.append(CLOCK() - t0)
    finally:
        venv.close()
    return {
        "num_envs": n,
        "steps": steps,
        "robot_steps_per_s": n * steps / min(times),
        "robot_steps_per_s_all": [n * steps / t for t in times],
    }


def batched_predict_times(specs: list[str], steps: int, n: int = PREDICT_BATCH, seed: int = 0) -> list[dict]:
    """Microseconds per robot-step of the whole batched `predict` (N = n robots of the vector env) of each spec,
    over `steps` steps (at most 200) of the policy's own closed loop."""
    import policies

    steps = max(1, min(steps, 200))
    rows = []
    for spec in specs:
        if spec.startswith("sb3:"):
            continue  # an SB3 agent is batched by SB3 itself; its single-env figure is in the predict table
        venv = _vector_env(n)
        try:
            policy = policies.make(spec, venv)
            obs, info = venv.reset(seed=seed)
            policy.reset(obs, info, seed=seed)
            total = 0.0
            for _ in range(steps):
                t0 = CLOCK()
                actions, _ = policy.predict(obs)
                total += CLOCK() - t0
                obs, *_ = venv.step(actions)
            rows.append({"policy": spec, "status": "ok", "num_envs": n, "us_per_robot_step": total / (n * steps) * 1e6})
        except Exception as exc:
            rows.append({"policy": spec, "status": f"skipped: {exc}"})
        finally:
            venv.close()
    return rows


def batch_episodes_per_second(n: int, policy: str, seed: int = 0) -> dict:
    """Episodes/s of `n` 20 s kinematic episodes run as one batch (`eval.rollout.rollout_batch`)."""
    import policies
    from eval.rollout import rollout_batch

    venv = _vector_env(n)
    try:
        pol = policies.make(policy, venv)
        t0 = CLOCK()
        out = rollout_batch(venv, pol, seed)
        wall = CLOCK() - t0
    finally:
        venv.close()
    failed = [rec for rec, _ in out if rec["status"] != "ok"]
    steps = sum(rec["n_steps"] for rec, _ in out)
    return {
        "policy": policy,
        "episodes": n,
        "status": "ok" if not failed else "failed: " + failed[0]["error"].strip().splitlines()[-1],
        "episodes_per_s": n / wall,
        "robot_steps_per_s": steps / wall,
        "wall_s": wall,
    }


def paper_kinematic_seconds() -> dict:
    """CPU seconds of the kinematic half of `mobman-eval paper` (`eval.paper.reproduce(dynamics="kinematic",
    workers=1)`, in this process, into a temporary folder), and its wall seconds."""
    from eval.paper import reproduce
    from eval.schemas import MAX_RESULTS_BYTES, read_eval_json

    with tempfile.TemporaryDirectory(prefix="mobman-speed-paper-") as tmp:
        c0, w0 = CLOCK(), time.perf_counter()
        out = reproduce(out=tmp, dynamics="kinematic", workers=1, overwrite=True, progress=False)
        cpu, wall = CLOCK() - c0, time.perf_counter() - w0
        episodes = read_eval_json(out / "results.json", MAX_RESULTS_BYTES, "paper results file")["episodes"]
    return {
        "cpu_s": cpu,
        "wall_s": wall,
        "episodes": len(episodes),
        "failed": sum(r["status"] != "ok" for r in episodes),
        "policies": sorted({r["policy"] for r in episodes}),
    }


def peer_steps(steps: int, repeats: int, seed: int = 0) -> list[dict]:
    """Steps/s of each installed peer and of the kinematic env, timed interleaved (mobman, peer, mobman, peer,
    ...) in this process under random actions, resets not timed; the best repeat of each, and their ratio."""
    import importlib

    import gymnasium as gym

    rows: list[dict[str, Any]] = []
    for label, env_id, module in PEERS:
        try:
            if module:
                importlib.import_module(module)
            peer = gym.make(env_id)
        except Exception as exc:
            rows.append({"peer": label, "id": env_id, "status": f"not installed: {exc} (pip install 'mobman[bench]')"})
            continue
        ours = _env("kinematic")
        rng = np.random.default_rng(seed)
        peer.action_space.seed(seed)
        peer_actions = np.array([peer.action_space.sample() for _ in range(steps)])
        our_actions = rng.uniform(-0.2, 0.2, size=(steps, 8)).astype(np.float32)
        t_ours, t_peer = [], []
        try:
            for _ in range(repeats):
                ours.reset(seed=seed)
                t_ours.append(time_env_steps(ours, our_actions))
                peer.reset(seed=seed)
                t_peer.append(time_env_steps(peer, peer_actions))
        finally:
            ours.close()
            peer.close()
        rows.append(
            {
                "peer": label,
                "id": env_id,
                "status": "ok",
                "steps": steps,
                "peer_steps_per_s": steps / min(t_peer),
                "mobman_kinematic_steps_per_s": steps / min(t_ours),
                "ratio_mobman_to_peer": min(t_peer) / min(t_ours),
            }
        )
    return rows


def default_policies() -> list[str]:
    try:
        import policies

        names = list(policies.KNOWN_POLICIES)
    except Exception:
        names = ["zero", "random"]
    return names + ["sb3:sac-circle"]


@dataclass(frozen=True)
class SpeedConfig:
    """What one `mobman-eval speed` measures, and where it writes speed.json and speed.md."""

    steps: int = 4000
    """Control steps per timed block."""
    repeats: int = 3
    """Repeats per timed block; the best is reported (the least disturbed one on a shared machine)."""
    episodes: int = 8
    """20 s episodes per workers setting of the `eval.run` episodes/s rows."""
    policies: tuple[str, ...] | None = None
    """Policies whose predict is timed; None: every built-in name and sb3:sac-circle. Each is built first: an
    unknown one stops the benchmark before it starts."""
    batch_size: int = 64
    """Episodes of the batched-eval block (one vector env, one batched policy)."""
    peers: bool = False
    """Also race the installed peers (panda-gym PandaReach-v3, MuJoCo Reacher-v5; pip install "mobman[bench]")."""
    paper: bool = False
    """Also time the kinematic half of `mobman-eval paper` with 1 worker (about 20 s)."""
    out: str | None = None
    """Output directory; None: `runs/speed-<UTC timestamp>`."""
    overwrite: bool = False
    """Write into an existing non-empty `out` (files of the same name are replaced)."""
    progress: bool = True
    """Say what is being timed (stderr) and print the table (stdout)."""

    def validate(self) -> None:
        """Raise EvalError naming a count that is not an integer >= 1."""
        from eval.errors import EvalError
        from mobman_env.validation import integer

        for name in ("steps", "repeats", "episodes", "batch_size"):
            integer(f"--{name.replace('_', '-')}", getattr(self, name), low=1, error=EvalError)


def measure(config: SpeedConfig | None = None, progress=print) -> dict:
    """Every figure of the module docstring's table (and the peers' and the paper's when `config` asks), as the
    dict speed.json holds; `progress(message)` says what is being timed."""
    from eval.output.provenance import git_rev, versions

    c = config or SpeedConfig()
    steps, repeats, episodes, batch = c.steps, c.repeats, c.episodes, c.batch_size
    specs = list(c.policies) if c.policies else None

    load = os.getloadavg() if hasattr(os, "getloadavg") else None
    out: dict = {
        "schema": 1,
        "when": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "machine": {
            "cpus": os.cpu_count(),
            "platform": platform.platform(),
            "loadavg_1_5_15_at_start": list(load) if load else None,
        },
        "versions": versions(),
        "git": git_rev(),
        "settings": {
            "env": SPEED_ENV,
            "steps": steps,
            "repeats": repeats,
            "episodes": episodes,
            "batch": batch,
            "control_freq_hz": 100.0,
        },
    }
    from eval.execution.warmup import warm_kernels

    warm_kernels(announce=c.progress)  # a cold numba cache compiles here, said, and not inside the first timing
    progress("timing env vs bare PyBullet (kinematic, physics at 2/4/10 substeps) ...")
    blocks = [env_vs_bare("kinematic", 2, steps, repeats)]
    blocks += [env_vs_bare("physics", n, steps, repeats) for n in SUBSTEPS]
    out["env"] = blocks
    progress("timing predict per policy ...")
    out["predict"] = predict_times(specs or default_policies())
    progress("timing eval.run episodes/s with workers 1 and 2, unbatched and batched ...")
    out["episodes"] = [episodes_per_second(w, episodes, batch_size=b) for b in EVAL_BATCH_SIZES for w in WORKERS]
    progress("timing the vector env at N = 1, 64, 1024 and batched predict ...")
    out["vector"] = [vector_steps(n, steps, repeats) for n in VECTOR_SIZES]
    out["batched_predict"] = batched_predict_times(specs or default_policies(), steps)
    progress(f"timing batched eval ({batch} episodes of nnbc and clik) ...")
    out["batch_episodes"] = [batch_episodes_per_second(batch, p) for p in ("nnbc", "clik")]
    if c.paper:
        progress("timing the kinematic half of mobman-eval paper (1 worker) ...")
        out["paper"] = paper_kinematic_seconds()
    if c.peers:
        progress("racing the peers (PandaReach-v3, Reacher-v5) ...")
        out["peers"] = peer_steps(steps, repeats)
    return out


def markdown(res: dict) -> str:
    """The figures of `measure` as Markdown: `## Conditions` and `## Figures` (docs/performance.md's block)."""
    m, st = res["machine"], res["settings"]
    load = m["loadavg_1_5_15_at_start"]
    lines = [
        "# mobman speed",
        "",
        "## Conditions",
        "",
        (
            f"{m['cpus']} CPUs ({m['platform']}), load average {load[0]:.1f} at the start (1 min)"
            if load
            else f"{m['cpus']} CPUs ({m['platform']})"
        )
        + f"; {res['when']}; best of {st['repeats']} repeats of {st['steps']} steps; {SPEED_ENV}, 100 Hz; steps/s "
        "per CPU-second of this process except the `eval.run` rows (wall time, worker start-up included).",
        "",
        "## Figures",
        "",
        "| figure | value |",
        "|---|---|",
    ]
    env = {(b["dynamics"], b["n_substeps"]): b for b in res["env"]}
    kin = env[("kinematic", 2)]
    lines.append(f"| kinematic env (one robot, `gym.make`) | {kin['env_steps_per_s']:,.0f} steps/s |")
    for n in SUBSTEPS:
        b = env[("physics", n)]
        lines.append(
            f"| physics env, {n} substeps | {b['env_steps_per_s']:,.0f} steps/s; bare PyBullet "
            f"{b['bare_steps_per_s']:,.0f}: env/bare {b['ratio_env_to_bare']:.2f} |"
        )
    for v in res.get("vector", []):
        lines.append(
            f"| vector env, N = {v['num_envs']:,} (kinematic, one process) | {v['robot_steps_per_s']:,.0f} "
            f"robot-steps/s ({v['robot_steps_per_s'] / kin['env_steps_per_s']:.1f}x one env) |"
        )
    pred = [r for r in res["predict"] if r["status"] == "ok"]
    if pred:
        text = ", ".join(f"`{r['policy']}` {r['predict_us_median']:.0f}" for r in pred)
        lines.append(f"| `predict`, median us, one env | {text} |")
    bp = [r for r in res.get("batched_predict", []) if r["status"] == "ok"]
    if bp:
        text = ", ".join(f"`{r['policy']}` {r['us_per_robot_step']:.1f}" for r in bp)
        lines.append(f"| batched `predict`, us per robot-step (N = {bp[0]['num_envs']}) | {text} |")
    for e in res["episodes"]:
        batch = f", batch size {e['batch_size']}" if "batch_size" in e else ""  # files before batching: no key
        lines.append(
            f"| episodes/s, 20 s kinematic `{e['policy']}`, `eval.run` with {e['workers']} worker(s){batch} | "
            f"{e['episodes_per_s']:.2f} |"
        )
    for e in res.get("batch_episodes", []):
        if e["status"] == "ok":
            lines.append(
                f"| episodes/s, 20 s kinematic `{e['policy']}`, one batch of {e['episodes']} "
                f"(`eval.rollout.rollout_batch`) | {e['episodes_per_s']:.2f} |"
            )
    if "paper" in res:
        pp = res["paper"]
        lines.append(
            f"| `mobman-eval paper --dynamics kinematic --workers 1` ({pp['episodes']} episodes, "
            f"{len(pp['policies'])} controllers, figures included) | {pp['cpu_s']:.1f} s CPU ({pp['wall_s']:.1f} s wall) |"
        )
    for p in res.get("peers", []):
        if p["status"] == "ok":
            lines.append(
                f"| vs {p['peer']} `{p['id']}` (interleaved, same process) | peer {p['peer_steps_per_s']:,.0f} "
                f"steps/s, mobman kinematic {p['mobman_kinematic_steps_per_s']:,.0f}: "
                f"{p['ratio_mobman_to_peer']:.2f}x |"
            )
    return "\n".join(lines) + "\n"


def print_table(res: dict) -> None:
    from rich.table import Table

    from eval.output.tables import console

    c = console()
    t = Table(title=f"env steps/s ({res['settings']['env']}, 100 Hz control, best of {res['settings']['repeats']})")
    for h in ("dynamics", "substeps", "env steps/s", "bare PyBullet steps/s", "env / bare", "sim s per wall s"):
        t.add_column(h, justify="right")
    for b in res["env"]:
        t.add_row(
            b["dynamics"],
            str(b["n_substeps"]) if b["dynamics"] == "physics" else "- (bare at 2)",
            f"{b['env_steps_per_s']:,.0f}",
            f"{b['bare_steps_per_s']:,.0f}",
            f"{b['ratio_env_to_bare']:.2f}",
            f"{b['env_steps_per_s'] / 100.0:.0f}",
        )
    c.print(t)
    t = Table(title="predict, whole call (µs), one kinematic episode")
    for h in ("policy", "median", "p99", "status"):
        t.add_column(h, justify="left" if h in ("policy", "status") else "right")
    for r in res["predict"]:
        t.add_row(
            r["policy"],
            f"{r['predict_us_median']:.0f}" if "predict_us_median" in r else "-",
            f"{r['predict_us_p99']:.0f}" if "predict_us_p99" in r else "-",
            r["status"].split(":")[0] + (" (reason in speed.json)" if r["status"] != "ok" else ""),
        )
    c.print(t)
    t = Table(title="episodes/s (20 s kinematic nnbc episodes, worker start-up included)")
    for h in ("workers", "batch size", "processes", "episodes", "episodes/s", "steps/s incl. policy", "wall s"):
        t.add_column(h, justify="right")
    t.add_column("s per episode", justify="right")
    for e in res["episodes"]:
        t.add_row(
            str(e["workers"]),
            str(e.get("batch_size", 1)),
            str(e["processes"]),
            str(e["episodes"]),
            f"{e['episodes_per_s']:.2f}",
            f"{e['env_steps_per_s']:,.0f}",
            f"{e['run_wall_s']:.1f}",
            f"{e['episode_wall_s_median']:.2f}",
        )
    c.print(t)
    load = res["machine"]["loadavg_1_5_15_at_start"]
    if load:
        c.print(f"{res['machine']['cpus']} CPUs, load average at start {load[0]:.2f} (1 min)")
