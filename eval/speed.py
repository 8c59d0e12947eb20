"""The speed benchmark: `mobman-eval speed` or `python -m eval.speed` (measures; asserts nothing).

What it measures, all in the same run so that the ratios compare like with like on a shared machine:

| figure | how |
|---|---|
| env steps/s (kinematic, physics) | `env.step` of `gym.make("WheeledPuma-Circle-v0", dynamics=...)` (with Gymnasium's wrappers) under small random actions, resets not timed |
| bare PyBullet steps/s | the same robot in the same client (`env.unwrapped.sim.client`) from the same start under the same commands: one `setJointMotorControlArray` and `n_substeps` x `stepSimulation()` per control step, nothing else (stepping cost depends on the motion, so an idle robot is no fair baseline) |
| ratio | env steps/s / bare steps/s at the same substeps |
| physics at 2, 4, 10 substeps | env and bare steps/s at each |
| predict microseconds | the whole `predict` call of each built-in policy over one kinematic episode (median, p99) |
| episodes/s | `eval.run` of 20 s kinematic `nnbc` episodes with `workers` 1 and 2 (worker start-up included) |

Each timed block is repeated (`--repeats`, interleaving env and bare runs) and the best repeat is reported: on
a machine shared with other jobs the best repeat is the least disturbed one. The load average at the start is
recorded beside the figures. Writes `speed.json` into `--out` and prints a table.
"""

from __future__ import annotations

import os
import platform
import tempfile
import time
from datetime import datetime, timezone

import numpy as np

SPEED_ENV = "WheeledPuma-Circle-v0"
SUBSTEPS = (2, 4, 10)
WORKERS = (1, 2)


# --- timed blocks ----------------------------------------------------------------------------------------


def _env(dynamics: str, n_substeps: int = 2):
    from eval.rollout import make_env

    return make_env(SPEED_ENV, dynamics, env_kwargs={"n_substeps": n_substeps} if dynamics == "physics" else {})


def time_env_steps(env, actions: np.ndarray) -> float:
    """Seconds for `len(actions)` env steps (resets at episode ends are not timed)."""
    total = 0.0
    i = 0
    n = len(actions)
    clock = time.perf_counter
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
    t0 = time.perf_counter()
    for u in targets:
        control(body, ids, mode, targetVelocities=u, forces=forces)
        for _ in range(n_substeps):
            step()
    return time.perf_counter() - t0


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

    rows = []
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


def episodes_per_second(workers: int, episodes: int, policy: str = "nnbc", seed: int = 0) -> dict:
    from eval.config import EvalConfig
    from eval.runner import run

    with tempfile.TemporaryDirectory(prefix="mobman-speed-") as tmp:
        cfg = EvalConfig(
            envs=(SPEED_ENV,),
            policies=(policy,),
            episodes=episodes,
            seed=seed,
            out=tmp,
            overwrite=True,
            workers=workers,
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


def default_policies() -> list[str]:
    try:
        import policies

        names = list(policies.KNOWN_POLICIES)
    except Exception:
        names = ["zero", "random"]
    return names + ["sb3:sac-circle"]


def measure(
    steps: int = 4000, repeats: int = 3, episodes: int = 8, specs: list[str] | None = None, progress=print
) -> dict:
    from eval.output.provenance import git_rev, versions

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
            "control_freq_hz": 100.0,
        },
    }
    progress("timing env vs bare PyBullet (kinematic, physics at 2/4/10 substeps) ...")
    blocks = [env_vs_bare("kinematic", 2, steps, repeats)]
    blocks += [env_vs_bare("physics", n, steps, repeats) for n in SUBSTEPS]
    out["env"] = blocks
    progress("timing predict per policy ...")
    out["predict"] = predict_times(specs or default_policies())
    progress("timing episodes/s with workers 1 and 2 ...")
    out["episodes"] = [episodes_per_second(w, episodes) for w in WORKERS]
    return out


def print_table(res: dict) -> None:
    from rich.console import Console
    from rich.table import Table

    c = Console()
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
    for h in ("workers", "processes", "episodes", "episodes/s", "steps/s incl. policy", "wall s", "s per episode"):
        t.add_column(h, justify="right")
    for e in res["episodes"]:
        t.add_row(
            str(e["workers"]),
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
