"""The nnbc-plus v5 development panel: four robots x four tasks x development seeds, a few conditions, one or
more controller specs, on the native vector env (kinematic). Prints one compact CSV row per (spec, condition):
successes, clean successes, max-error median and max (mm), cmd_accel_rms median (rad/s^2), max-error IQM (mm).

    PYTHONPATH=$PWD python docs/results/nnbc-plus-v5/panel.py --specs "nnbc-plus;nnbc-plus-wb" --seed 0 --seeds 4
    python docs/results/nnbc-plus-v5/panel.py --markdown experiments/m-probe-noise-start.csv  # the CSV as a table

Development seeds only (below 10,000). Conditions: `CONDITIONS` below (the page's names for the dev track's and
the issue's named ones), or any kinematic condition of the one conditions table (`eval.conditions`) by its name.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
from scipy.stats import trim_mean

import policies
from eval.conditions import CONDITIONS as TABLE
from eval.rollout import make_vector_env, rollout_batch

ROBOTS = ("WheeledPuma", "WheeledUR5", "WheeledPanda", "WheeledRandomArm")
TASKS = ("Circle", "Lemniscate", "Line", "Random")
#: the page's condition names -> the one conditions table's (`eval.conditions`)
TABLE_NAMES = {
    "default": "default",
    "noise": "noise",
    "jv05": "jv05",
    "heavy15": "heavy15",
    "lag50": "lag",
    "lag150": "lag150",
    "wear20": "wear20",
    "yaw": "yaw-noise",
    "drift": "drift",
}
#: name -> (model_error, obs_noise, env_kwargs), read from the table
CONDITIONS = {
    page: (TABLE[name].model_error, TABLE[name].obs_noise, TABLE[name].extra_kwargs)
    for page, name in TABLE_NAMES.items()
}


def run_cell(spec: str, cond: str, seed: int, seeds: int, robots=ROBOTS, tasks=TASKS) -> list[dict]:
    if cond in CONDITIONS:
        me, on, kw = CONDITIONS[cond]
    else:
        c = TABLE[cond]
        assert c.dynamics == "kinematic", f"{cond}: the panel runs kinematic conditions"
        me, on, kw = c.model_error, c.obs_noise, c.extra_kwargs
    recs = []
    for robot in robots:
        for task in tasks:
            venv = make_vector_env(f"{robot}-{task}-v0", seeds, "kinematic", me, on, kw)
            pol = policies.make(spec, venv)
            for rec, _ in rollout_batch(venv, pol, seed):
                rec["robot"], rec["task"] = robot, task
                recs.append(rec)
            venv.close()
    return recs


def summary(recs: list[dict]) -> str:
    mx = np.array([r["max_error_m"] if r["max_error_m"] is not None else np.inf for r in recs]) * 1e3
    acc = np.array([r["cmd_accel_rms"] if r["cmd_accel_rms"] is not None else np.nan for r in recs])
    ok = sum(bool(r["success"]) for r in recs)
    clean = sum(bool(r["clean_success"]) for r in recs)
    lost = ";".join(f"{r['robot'][7:]}-{r['task']}-{r['seed']}:{m:.1f}" for r, m in zip(recs, mx) if m > 6.0)
    return (
        f"{ok}/{len(recs)},{clean}/{len(recs)},{np.median(mx):.3f},{np.max(mx):.1f},"
        f"{np.nanmedian(acc):.2f},{trim_mean(mx, 0.25):.3f},{lost}"
    )


def markdown(path: str) -> str:
    """The panel's CSV (its `main`'s output) as a markdown table: successes and clean successes of 6 mm, the
    max error's median, largest and IQM (mm) and the commands' acceleration RMS median (rad/s^2)."""
    import csv

    lines = [
        "| controller | condition | success | clean | max error median / IQM / largest (mm) | accel RMS median |",
        "|---|---|---|---|---|---|",
    ]
    with open(path, newline="") as f:
        for r in csv.DictReader(f):
            lines.append(
                f"| `{r['spec']}` | {r['condition']} | {r['success']} | {r['clean']} | {r['max_med_mm']} / "
                f"{r['max_iqm_mm']} / {r['max_max_mm']} | {r['accel_med']} |"
            )
    return "\n".join(lines) + "\n"


def main(argv=None) -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--markdown", metavar="CSV", help="print a panel CSV as a markdown table, run nothing")
    p.add_argument("--specs", default="nnbc-plus")
    p.add_argument("--conditions", default=",".join(CONDITIONS))
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--seeds", type=int, default=4)
    p.add_argument("--robots", default=",".join(ROBOTS))
    p.add_argument("--tasks", default=",".join(TASKS))
    a = p.parse_args(argv)
    if a.markdown:
        sys.stdout.write(markdown(a.markdown))
        return
    assert a.seed + a.seeds <= 10_000, "development seeds only"
    print("spec,condition,success,clean,max_med_mm,max_max_mm,accel_med,max_iqm_mm,lost", flush=True)
    for spec in a.specs.split(";"):
        for cond in a.conditions.split(","):
            recs = run_cell(spec, cond, a.seed, a.seeds, a.robots.split(","), a.tasks.split(","))
            print(f'"{spec}",{cond},{summary(recs)}', flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
