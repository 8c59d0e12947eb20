"""Statistics of a multi-seed RL report (`mobman-train report`): pure functions over rows, no files.

The statistics are the protocol's (`eval.metrics`): the IQM is `eval.metrics.iqm` (scipy's `trim_mean(x,
0.25)`, rliable's IQM) and its 95% interval `eval.metrics.iqm_ci95`, the stratified percentile bootstrap with
`BOOTSTRAP_RESAMPLES` resamples from the fixed `BOOTSTRAP_SEED`. What is resampled:

* **Learning curves** (`curve_rows`): at every evaluation step, the IQM over the training seeds of each seed's
  periodic-evaluation figure (median max error over its development episodes); the interval resamples the
  seeds (one stratum). With 5 seeds the IQM is the mean of the middle 3.
* **Final tables** (`family_row`): the values are a matrix, training seeds x reported episodes, of each run's
  final model on the same episodes. The IQM is over all of them; the interval is rliable's stratified
  bootstrap with the episodes as its tasks: within every episode (a stratum) the training seeds are drawn with
  replacement. So the interval is over training seeds (the run-to-run spread a reader who retrains meets), on
  the fixed episodes that every agent and controller faces. The success rate's interval is the same bootstrap
  of the mean success (`success_ci95`; a Wilson interval over the pooled episodes would treat episodes of
  one agent as independent agents). As in `eval.metrics.aggregate`, an episode that failed to run (an
  exception, status not "ok") counts as a failure of the success rate and in `n_failed`, and the error
  statistics are over the episodes that ran. One seed has no interval over seeds (None).
* **Median-seed model** (`median_run`): the run whose IQM max error over the reported episodes is the median
  of its family's (the lower median for an even count; ties broken by the smaller seed).

Imports: numpy and `eval.metrics`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from eval import metrics as M

#: Periodic-evaluation column of `learning_curve.csv` that the curves aggregate.
CURVE_METRIC = "median_max_error_m"


def success_ci95(
    success: np.ndarray, *, resamples: int = M.BOOTSTRAP_RESAMPLES, seed: int = M.BOOTSTRAP_SEED
) -> list[float]:
    """95% percentile interval of the mean of a (training seeds x episodes) 0/1 matrix over resamples of its
    rows drawn independently within every column (episode): the stratified bootstrap of `eval.metrics.iqm_ci95`
    (same resamples and generator seed, episodes as strata) applied to the mean instead of the IQM."""
    m = np.asarray(success, float)
    n_seeds, n_eps = m.shape
    rng = np.random.default_rng(seed)
    picks = rng.integers(0, n_seeds, size=(resamples, n_seeds, n_eps))
    means = m[picks, np.arange(n_eps)[None, None, :]].mean(axis=(1, 2))
    low, high = np.percentile(means, [2.5, 97.5])
    return [float(low), float(high)]


def family_row(family: str, runs: Sequence[dict]) -> dict:
    """The final-table row of one family from its runs' episode records (`run["episodes"]`, the same seeds in
    every run): n seeds, n episodes, IQM max error with its interval, median, success rate with its interval,
    and the per-seed IQMs."""
    seeds = [r["seed"] for r in runs]
    episode_seeds = [e["seed"] for e in runs[0]["episodes"]]
    for r in runs:
        if [e["seed"] for e in r["episodes"]] != episode_seeds:
            raise ValueError(
                f"{family}: run {r['name']} was evaluated on episodes {[e['seed'] for e in r['episodes']]}, "
                f"{runs[0]['name']} on {episode_seeds}; evaluate every run on the same episodes"
            )
    ran = [[e for e in r["episodes"] if e.get("status") == "ok"] for r in runs]
    by_episode: dict[int, list[float]] = {}
    for eps in ran:
        for e in eps:
            by_episode.setdefault(e["seed"], []).append(e["max_error_m"])
    values = [v for eps in ran for v in (e["max_error_m"] for e in eps)]
    success = np.array([[bool(e["success"]) for e in r["episodes"]] for r in runs], float)
    return {
        "family": family,
        "n_seeds": len(runs),
        "seeds": seeds,
        "n_episodes": int(success.size),
        "n_failed": int(success.size) - len(values),
        "n_tipped_over": sum(bool(e.get("tipped_over")) for eps in ran for e in eps),
        "max_error_m": {
            "iqm": M.iqm(values),
            "iqm_ci95": M.iqm_ci95(list(by_episode.values())) if len(runs) > 1 else None,
            "median": float(np.median(values)) if values else None,
            "per_seed_iqm": [M.iqm(e["max_error_m"] for e in eps) for eps in ran],
        },
        "success_rate": float(success.mean()),
        "success_rate_ci95": success_ci95(success) if len(runs) > 1 else None,
        "per_seed_success_rate": [float(v) for v in success.mean(axis=1)],
    }


def median_run(runs: Sequence[dict], key: Callable[[dict], float]) -> dict:
    """The run whose `key` (IQM max error on the reported episodes) is the median of `runs`' (the lower one of
    the middle two for an even count; ties: the smaller seed)."""
    if not runs:
        raise ValueError("no finished run to choose a median-seed model from")
    ordered = sorted(runs, key=lambda r: (key(r), r["seed"]))
    return ordered[(len(ordered) - 1) // 2]


def curve_rows(family: str, runs: Sequence[dict], metric: str = CURVE_METRIC) -> list[dict]:
    """One row per evaluation step of the family's learning curves: the step, how many seeds were evaluated
    there, the IQM over them of each seed's `metric` and its 95% bootstrap interval over the seeds, and the
    median wall-clock time (s) at which the seeds reached that step."""
    by_step: dict[int, list[tuple[float, float]]] = {}
    for r in runs:
        for row in r["curve"]:
            by_step.setdefault(int(row["timesteps"]), []).append((float(row[metric]), float(row["wall_s"])))
    out = []
    for step in sorted(by_step):
        values = [v for v, _ in by_step[step]]
        ci = M.iqm_ci95([values]) if len(values) > 1 else None
        out.append(
            {
                "family": family,
                "timesteps": step,
                "n_seeds": len(values),
                f"{metric}_iqm": M.iqm(values),
                f"{metric}_ci95_low": None if ci is None else ci[0],
                f"{metric}_ci95_high": None if ci is None else ci[1],
                "wall_s_median": float(np.median([w for _, w in by_step[step]])),
            }
        )
    return out
