"""Step-by-step diagnosis of one `nnbc-plus` episode of an issue-16 condition (development seeds only): what the
estimate gets wrong, where the filter thinks it is wrong, and whether the plant still obeys y = J x.

Usage (from the repository root):

    PYTHONPATH=$PWD python docs/results/nnbc-plus-v2/trace.py --policy nnbc-plus --condition circle-5s \
        --mode physics --seed 0 --steps 100 345 --every 5 --out docs/results/nnbc-plus-v2/trace-circle5s.md

It may read the true robot (`env.unwrapped.true_params`): it is a diagnosis beside the controller, never
part of it. Columns, at the observation the controller acted on at that step:

| column | meaning |
|---|---|
| err | tracking error \\|r_a - r_d\\|, mm |
| \\|E\\| | \\|J_hat - J\\|_F, m/rad (J the true whole-body Jacobian) |
| row / null | \\|E J^+ J\\|_F and \\|E (I - J^+ J)\\|_F: the error in J's row space and in its null space |
| P top / E top | the filter's standard deviation along the top eigenvector v of the covariance of one row of J, and the actual \\|E v\\| / sqrt(3) |
| u-dir | \\|E u\\| / (sqrt(3) \\|u\\|): the error along the commanded direction |
| sv est / true | smallest singular value of J_hat and of J, m/rad |
| \\|y - Jx\\| | the measured end-effector velocity minus J times the measured actuator speeds, mm/s |
| slip | the measured arm-base velocity minus the unicycle's (wheel speeds through the true wheel map), mm/s |
| u1, du1 | joint 1's command (rad/s) and its change since the previous step (rad/s per step) |
"""

from __future__ import annotations

import argparse
import importlib.util
import platform
import subprocess
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent


def _conditions():
    spec = importlib.util.spec_from_file_location("conditions", HERE / "conditions.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def trace(
    spec: str, condition: str, task: str | None, mode: str, seed: int, first: int, last: int, every: int
) -> tuple[list[dict], dict]:
    """One row per traced step (see the module docstring), and the largest tracking error (mm) and slip (mm/s)
    over every step up to `last`. A controller without a Jacobian estimate (a known-model one) gets only the
    plant's columns."""
    from eval.rollout import make_env, make_policy
    from mobman_env.kinematics import arm_base_jacobian, whole_body_jacobian
    from policies.base import policy_seed

    cond = _conditions()
    if seed >= 1000:
        raise SystemExit(f"trace.py is a development tool: seeds 0-999 only, got {seed}")
    robot = cond.CONDITIONS[condition][2].get("robot", "Puma")
    task = task or cond.CONDITIONS[condition][0][0]
    env = make_env(f"Wheeled{robot}-{task}-v0", dynamics=mode, env_kwargs=cond.env_kwargs(condition, seed))
    rows = []
    try:
        base = env.unwrapped
        obs, info = env.reset(seed=seed)
        policy = make_policy(spec, env, seed)
        policy.reset(obs, info, seed=policy_seed(seed))  # (as eval's rollout: the episode of the conditions' runs)
        n = len(base.action_scale)
        prev_u1 = 0.0
        worst = {"err_mm": 0.0, "slip_mm_s": 0.0, "steps": 0}
        for k in range(last + 1):
            action, _ = policy.predict(obs)
            u = np.asarray(action, float).reshape(-1) * np.asarray(base.action_scale)
            u1 = float(u[0])
            q, x, yaw = obs["joint_pos"], obs["joint_vel"], float(obs["base_yaw"][0])
            slip = 1e3 * float(np.linalg.norm(obs["arm_base_vel"] - arm_base_jacobian(base.true_params, yaw) @ x))
            err = 1e3 * float(np.linalg.norm(obs["ee_pos"] - obs["target_pos"]))
            worst = {"err_mm": max(worst["err_mm"], err), "slip_mm_s": max(worst["slip_mm_s"], slip), "steps": k + 1}
            estimate = getattr(policy, "jacobian_estimate", None)
            if k >= first and (k - first) % every == 0:
                J = whole_body_jacobian(base.true_params, q[: n - 2], yaw)
                r = {"step": k, "err_mm": err, "res_mms": 1e3 * float(np.linalg.norm(obs["ee_vel"] - J @ x))}
                r.update(slip_mms=slip, u1=u1, du1=u1 - prev_u1, sv_true=float(np.linalg.svd(J, compute_uv=False)[-1]))
                if estimate is not None:
                    E = estimate - J
                    row = E @ np.linalg.pinv(J) @ J
                    ev, V = np.linalg.eigh(policy.P[:n, :n])
                    r.update(
                        E=float(np.linalg.norm(E)),
                        row=float(np.linalg.norm(row)),
                        null=float(np.linalg.norm(E - row)),
                        p_top=float(np.sqrt(ev[-1])),
                        e_top=float(np.linalg.norm(E @ V[:, -1]) / np.sqrt(3)),
                        u_dir=float(np.linalg.norm(E @ u) / (np.sqrt(3) * max(np.linalg.norm(u), 1e-12))),
                        sv_est=float(np.linalg.svd(estimate, compute_uv=False)[-1]),
                    )
                rows.append(r)
            prev_u1 = u1
            obs, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                break
    finally:
        env.close()
    return rows, worst


def _f(r: dict, key: str, fmt: str) -> str:
    return format(r[key], fmt) if key in r else "-"


def markdown(traces: list[tuple[int, list[dict], dict]], command: str) -> str:
    try:
        git = subprocess.run(["git", "rev-parse", "--short=12", "HEAD"], capture_output=True, text=True).stdout.strip()
    except OSError:
        git = "unknown"
    out = [
        f"# nnbc-plus: step trace\n\n`{command}` (git {git}, {platform.machine()}); columns defined in "
        "`docs/results/nnbc-plus-v2/trace.py`.\n"
    ]
    for seed, rows, worst in traces:
        out.append(
            f"\n## seed {seed}\n\nOver steps 0-{worst['steps'] - 1}: max tracking error {worst['err_mm']:.1f} mm, "
            f"max slip {worst['slip_mm_s']:.1f} mm/s.\n\n"
            "| step | err (mm) | \\|E\\| | row | null | P top | E top | u-dir | sv est / true | \\|y - Jx\\| (mm/s) "
            "| slip (mm/s) | u1 | du1 |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|\n"
        )
        out.extend(
            f"| {r['step']} | {r['err_mm']:.1f} | {_f(r, 'E', '.3f')} | {_f(r, 'row', '.3f')} | {_f(r, 'null', '.3f')} "
            f"| {_f(r, 'p_top', '.3f')} | {_f(r, 'e_top', '.3f')} | {_f(r, 'u_dir', '.4f')} "
            f"| {_f(r, 'sv_est', '.3f')} / {r['sv_true']:.3f} | {r['res_mms']:.1f} | {r['slip_mms']:.1f} | {r['u1']:.2f} "
            f"| {r['du1']:+.2f} |\n"
            for r in rows
        )
    return "".join(out)


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--policy", default="nnbc-plus")
    p.add_argument("--condition", default="circle-5s", choices=sorted(_conditions().CONDITIONS))
    p.add_argument("--task", default=None, help="default: the condition's first task")
    p.add_argument("--mode", default="physics", choices=("kinematic", "physics"))
    p.add_argument("--seed", type=int, nargs="+", default=[0])
    p.add_argument("--steps", type=int, nargs=2, default=(100, 345), metavar=("FIRST", "LAST"))
    p.add_argument("--every", type=int, default=5)
    p.add_argument("--out", type=Path, required=True)
    a = p.parse_args(argv)
    traces = []
    for seed in a.seed:
        rows, worst = trace(a.policy, a.condition, a.task, a.mode, seed, a.steps[0], a.steps[1], a.every)
        traces.append((seed, rows, worst))
    command = "docs/results/nnbc-plus-v2/trace.py " + " ".join(sys.argv[1:] if argv is None else argv)
    a.out.write_text(markdown(traces, command))
    print(f"wrote {a.out} ({sum(len(t[1]) for t in traces)} steps)")


if __name__ == "__main__":
    main()
