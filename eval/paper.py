"""`mobman-eval paper`: the paper's section IV in one command, and `paper.md` setting its claims beside ours.

What runs: `WheeledPuma-Circle-v0` (theta(0) = [0, pi/4, 0, 2pi/3, -pi/4, 0] rad, wheels 0, heading pi, the
circle of radius 0.4 m tilted pi/6 over 20 s), `nnbc` (gamma = mu = 10) against `jmpi`, with `oracle` (eq. (10)
on the true robot, gamma = 10), `nnbc-full` and, when they are registered in this install, `nnbc-plus`, `clik`
(eq. (10) on the nominal model: the closed-loop controller a practitioner would run beside JMPI) and
`qp-oracle` (a joint-limit-aware QP on the true robot: the known-model ceiling), at their default gains; in both
dynamics modes (kinematic = the paper's ideal model, physics = PyBullet contact dynamics); 20 reported seeds
(10,000 ...) by default, each a different "worn" true robot (model_error 0.05). `nnbc` and `oracle` keep the
paper's gamma = 10: the oracle runs as `oracle:gamma=10` (every closed-loop law defaults to 20 1/s), and `nnbc`
gets its gains set in the spec should its defaults ever differ from the paper's.

paper.md prints chaotic controllers' errors with the digits they have (`eval.output.precision`).

Writes, beside the usual run files (results.json, summary.md, plots/ ...):

* `fig2a_<dynamics>.png` (NNBC's path and platform trace), `fig2b_<dynamics>.png` (NNBC's error per axis),
  `fig3_<dynamics>.png` (NNBC vs JMPI), all of seed 10,000 — the paper's Fig. 2a, 2b and 3;
* `paper.md`: each claim of the paper beside what was measured, and where and why they differ.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from eval.config import EvalConfig
from eval.errors import EvalError
from eval.metrics import DEFAULT_TOLERANCE
from eval.output.files import atomic_save_figure, atomic_write_text
from eval.output.precision import CHAOTIC_NOTE, format_mm, format_value, is_chaotic
from eval.output.tables import SUMMARY_HEADER, markdown_table, summary_row

PAPER_ENV = "WheeledPuma-Circle-v0"
PAPER_SEED = 10_000  # reported seeds start here (DESIGN "Seeds")
PAPER_GAMMA = 10.0  # the paper's gamma = mu = 10
PAPER_MAX_ERROR = DEFAULT_TOLERANCE  # m: "the maximum tracking error is not more than 0.006 m"
PAPER_PATH_SIZE = (0.8, 0.8, 0.2)  # m: "the scale of the desired path is 0.8 m x 0.8 m x 0.2 m"
#: the oracle with the paper's gain (every closed-loop law's default is 20 1/s; the paper's section IV uses 10)
ORACLE = f"oracle:gamma={PAPER_GAMMA:g}"
CORE_POLICIES = ("nnbc", "jmpi", ORACLE, "nnbc-full")
#: run when registered, at their default gains (`clik`, `qp-oracle`: the baselines the paper did not run)
OPTIONAL_POLICIES = ("nnbc-plus", "clik", "qp-oracle")
#: policies run by name whose defaults must equal the paper's gains (else the spec sets them): {name: fields}
PAPER_GAINS = {"nnbc": ("gamma", "mu")}
#: the dynamics modes paper.md reports, in its order
PAPER_DYNAMICS = ("kinematic", "physics")


@dataclass(frozen=True)
class PaperConfig:
    """What one `mobman-eval paper` runs besides what the paper fixes (env, policies, first seed: the module
    docstring)."""

    out: str | None = None
    """Output directory; None: `runs/paper-<UTC timestamp>`."""
    overwrite: bool = False
    """Write into an existing non-empty `out` (files of the same name are replaced)."""
    seeds: int = 20
    """Reported seeds 10000, 10001, ...: each a different worn true robot (the paper's section IV has 20)."""
    dynamics: tuple[str, ...] = PAPER_DYNAMICS
    """Dynamics modes ("kinematic": the paper's idealised model; "physics": PyBullet contact dynamics), reported
    in this order. Default both: the paper's claims are checked in its own setting and in the realistic one."""
    workers: int = 2
    """Worker processes (results do not depend on it; 2 halves the physics half on a two-core machine)."""
    batch_size: int = EvalConfig.batch_size
    """Most kinematic episodes stepped together through one vector env (`EvalConfig.batch_size`)."""
    video: bool = False
    """Also write videos of seed 10000 (slow)."""
    progress: bool = True
    """Show a progress bar (stderr) and where paper.md is (stdout)."""

    def __post_init__(self) -> None:
        modes = (self.dynamics,) if isinstance(self.dynamics, str) else tuple(self.dynamics)
        if modes == ("both",):  # the spelling of release 0.1 (the CLI says it is deprecated)
            modes = PAPER_DYNAMICS
        object.__setattr__(self, "dynamics", modes)

    def validate(self) -> None:
        """Raise EvalError naming the bad value, the accepted ones and the fix."""
        if isinstance(self.seeds, bool) or not isinstance(self.seeds, int) or self.seeds < 1:
            raise EvalError(f"--seeds must be an integer >= 1, got {self.seeds!r}")
        unknown = [m for m in self.dynamics if m not in PAPER_DYNAMICS]
        if unknown or not self.dynamics or len(set(self.dynamics)) != len(self.dynamics):
            raise EvalError(
                f"--dynamics {','.join(self.dynamics)!r}: give each of {', '.join(PAPER_DYNAMICS)} at most once "
                f"(default: both)"
            )

    @property
    def modes(self) -> tuple[str, ...]:
        """The dynamics modes in the report's order."""
        return tuple(m for m in PAPER_DYNAMICS if m in self.dynamics)


def choose_policies(dynamics: str) -> tuple[tuple[str, ...], list[str]]:
    """The specs to run and notes about what was left out or adjusted (checked on a real env)."""
    import policies
    from eval.rollout import make_env
    from policies.registry import KNOWN_POLICIES

    notes = []
    specs = list(CORE_POLICIES)
    env = make_env(PAPER_ENV, dynamics)
    try:
        for name, gains in PAPER_GAINS.items():
            cfg = getattr(policies.make(name, env), "config", None)
            differ = [g for g in gains if cfg is not None and getattr(cfg, g, PAPER_GAMMA) != PAPER_GAMMA]
            if differ:
                spec = name + ":" + ",".join(f"{g}={PAPER_GAMMA:g}" for g in gains if hasattr(cfg, g))
                specs = [spec if s == name else s for s in specs]
                notes.append(f"the {name} default gains differ from the paper's; {spec.split(':')[1]} set explicitly")
        for name in OPTIONAL_POLICIES:
            if name not in KNOWN_POLICIES:
                notes.append(f"`{name}` is not registered in this install and was not run")
                continue
            try:
                policies.make(name, env)
                specs.append(name)
            except Exception as exc:
                notes.append(f"`{name}` was skipped: `policies.make({name!r}, env)` failed here ({exc})")
    finally:
        env.close()
    return tuple(specs), notes


def reproduce(config: PaperConfig | None = None, **changes: Any) -> Path:
    """Run the section IV experiment and write the figures and paper.md; returns the output directory.
    `changes` replace fields of `config` (default `PaperConfig()`), e.g. `reproduce(dynamics="kinematic")`."""
    from eval.runner import run

    paper = replace(config or PaperConfig(), **changes)
    paper.validate()
    modes = paper.modes
    specs, notes = choose_policies(modes[0])
    run_config = EvalConfig(
        envs=(PAPER_ENV,),
        policies=specs,
        episodes=paper.seeds,
        seed=PAPER_SEED,
        out=paper.out,
        overwrite=paper.overwrite,
        workers=paper.workers,
        batch_size=paper.batch_size,
        dynamics=modes,
        video=paper.video,
        save_arrays="first",
        progress=paper.progress,
        command="paper",
    )
    t0 = time.perf_counter()
    result = run(run_config)
    wall = time.perf_counter() - t0
    out_dir = Path(result.out)
    figures = write_figures(result, out_dir)
    atomic_write_text(out_dir / "paper.md", paper_markdown(result, specs, notes, figures, wall))
    return out_dir


# --- figures ---------------------------------------------------------------------------------------------


def _first_episode_traces(result, dyn: str) -> dict[str, dict]:
    traces = {}
    for rec in result.episodes:
        if rec["dynamics"] == dyn and rec["episode"] == 0 and rec["index"] in result.arrays:
            traces[rec["policy"]] = {**rec, **result.arrays[rec["index"]]}
    return traces


def write_figures(result, out_dir: Path) -> dict[str, list[str]]:
    import matplotlib.pyplot as plt

    from eval.output import plots

    written: dict[str, list[str]] = {}
    for dyn in result.results["config"]["dynamics"]:
        tr = _first_episode_traces(result, dyn)
        nnbc = next((tr[k] for k in tr if k.split(":")[0] == "nnbc"), None)
        jmpi = tr.get("jmpi")
        figs = []
        if nnbc is not None:
            figs += [
                (f"fig2a_{dyn}.png", plots.plot_paths_3d([nnbc])),
                (f"fig2b_{dyn}.png", plots.plot_axis_errors([nnbc])),
            ]
            if jmpi is not None:
                figs.append((f"fig3_{dyn}.png", plots.plot_paths_3d([nnbc, jmpi])))
        for name, fig in figs:
            atomic_save_figure(fig, out_dir / name)
            plt.close(fig)
            written.setdefault(dyn, []).append(name)
    return written


# --- paper.md --------------------------------------------------------------------------------------------


def path_extent(r_d: np.ndarray) -> np.ndarray:
    """Size of the desired path along x, y, z (max - min of the samples), m."""
    r_d = np.asarray(r_d, float)
    return r_d.max(axis=0) - r_d.min(axis=0)


def formula_extent(spec: dict) -> np.ndarray:
    """The paper's formula's size for a circle spec: x 2l, y 2l cos(tilt), z 2l sin(tilt) (l: the radius)."""
    r, tilt = float(spec["radius"]), float(spec["tilt"])
    return np.array([2 * r, 2 * r * math.cos(tilt), 2 * r * math.sin(tilt)])


def _size(v) -> str:
    return " x ".join(f"{x:.2f}" for x in v) + " m"


def _agg(result, policy: str, dyn: str) -> dict | None:
    for a in result.aggregate:
        if a["policy"] == policy and a["dynamics"] == dyn:
            return a
    return None


def _errs(result, policy: str, dyn: str) -> list[float]:
    return [
        r["max_error_m"]
        for r in result.episodes
        if r["policy"] == policy and r["dynamics"] == dyn and r["status"] == "ok"
    ]


def _mm(x, policy: str | None = None) -> str:
    """x (m) in mm with one decimal, or with the digits `policy`'s results have (`eval.output.precision`)."""
    if x is None:
        return "-"
    return (f"{x * 1e3:.1f}" if policy is None else format_mm(x, policy, 1)) + " mm"


def _claim_nnbc(result, nnbc: str, dyn: str) -> tuple[str, str]:
    a = _agg(result, nnbc, dyn)
    errs = _errs(result, nnbc, dyn)
    if a is None or not errs:
        return "no completed episode", "not measured"
    n_ok = sum(e <= PAPER_MAX_ERROR for e in errs)
    text = (
        f"max error median {_mm(a['max_error_m']['median'], nnbc)}, worst {_mm(max(errs), nnbc)}; "
        f"<= 6 mm in {n_ok}/{a['n']} seeds"
    )
    verdict = "holds" if n_ok == a["n"] else ("holds in most seeds" if n_ok >= 0.5 * a["n"] else "does not hold")
    return text, verdict


def _claim_jmpi(result, nnbc: str, dyn: str) -> tuple[str, str]:
    a, b = _agg(result, "jmpi", dyn), _agg(result, nnbc, dyn)
    errs = _errs(result, "jmpi", dyn)
    if a is None or not errs:
        return "no completed episode", "not measured"
    n_fail = sum(e > PAPER_MAX_ERROR for e in errs) + a["n_failed"]
    text = (
        f"max error median {_mm(a['max_error_m']['median'])} (best seed {_mm(min(errs))}); "
        f"> 6 mm in {n_fail}/{a['n']} seeds"
    )
    ratio = ""
    if b is not None and b["max_error_m"]["median"]:
        ratio = f", {a['max_error_m']['median'] / b['max_error_m']['median']:.2g} x NNBC's median"
    text += ratio
    verdict = "holds" if n_fail == a["n"] else ("holds in most seeds" if n_fail >= 0.5 * a["n"] else "does not hold")
    return text, verdict


def spec_of(specs, name: str) -> str | None:
    """The spec in `specs` that runs the registry policy `name` (`oracle:gamma=10` for "oracle"), or None."""
    return next((s for s in specs if s.split(":")[0] == name), None)


def paper_markdown(result, specs, notes, figures, wall_s: float) -> str:
    res = result.results
    cfg = res["config"]
    modes = cfg["dynamics"]
    nnbc = spec_of(specs, "nnbc")
    if nnbc is None:  # choose_policies always runs it: the claims are about it
        raise EvalError(f"paper.md compares NNBC with the others, but no nnbc spec was run ({', '.join(specs)})")
    oracle = spec_of(specs, "oracle") or ORACLE
    first = next((r for r in result.episodes if r["index"] in result.arrays), None)
    measured = path_extent(result.arrays[first["index"]]["r_d"]) if first else None
    spec = first["path"] if first else None
    formula = formula_extent(spec) if spec and spec.get("type") == "circle" else None
    n = cfg["episodes"]
    lines = [
        "# The paper's section IV, reproduced",
        "",
        f"`mobman-eval paper`: `{PAPER_ENV}` (theta(0) = [0, pi/4, 0, 2pi/3, -pi/4, 0] rad, wheels 0 rad, heading pi; "
        f"the circle of radius 0.4 m tilted pi/6, T_d = 20 s, 100 Hz control), {n} reported seeds "
        f"({cfg['seed']}..{cfg['seed'] + n - 1}), each a different true robot (link lengths, tool, wheel radius, "
        f"half track and mount offset off the nominal ones by {_pct(result)} relative std), dynamics: {', '.join(modes)}. "
        f"Policies: {', '.join(f'`{s}`' for s in specs)}; `{nnbc}` has the paper's gamma = mu = 10. Success = max tracking error "
        f"<= 6 mm over the whole 20 s. Ran in {wall_s:.0f} s with {cfg['workers']} worker(s); git `{res['git']}`.",
        "",
    ]
    if notes:
        lines += ["Notes: " + "; ".join(notes) + ".", ""]
    lines += ["## Claims", ""]
    rows = _claim_rows(result, nnbc, modes, measured, formula)
    lines += [markdown_table(("claim", "paper", "measured", "verdict"), rows), ""]

    lines += ["## Where we differ, and why", ""]
    lines += _differences(result, nnbc, modes, measured, formula, oracle)
    lines += ["", "## Baselines the paper did not run, and what they mean for its claims", ""]
    lines += _baselines(result, specs, nnbc, oracle, modes)
    lines += ["", "## All policies", ""]
    for dyn in modes:
        aggs = [a for a in result.aggregate if a["dynamics"] == dyn]
        lines += [f"### {dyn}", "", markdown_table(SUMMARY_HEADER, [summary_row(a) for a in aggs]), ""]
    lines += ["## Max error per seed (mm)", ""]
    lines += [_per_seed_table(result, specs, nnbc, oracle, modes), ""]
    lines += [f"## Figures (seed {cfg['seed']})", ""]
    for dyn in modes:
        names = figures.get(dyn, [])
        lines += [
            f"* {dyn}: "
            + ", ".join(f"[{nm}]({nm})" for nm in names)
            + f"; all policies: plots/{PAPER_ENV}_{dyn}_paths3d.png, _axis_errors.png, _error_norm.png"
        ]
    lines += [
        "",
        "Fig. 2a = NNBC's path and platform trace, Fig. 2b = NNBC's error per axis, Fig. 3 = NNBC vs JMPI.",
        "Every number above comes from results.json in this directory.",
        "",
    ]
    return "\n".join(lines)


def _claim_rows(result, nnbc: str, modes, measured, formula) -> list[list[str]]:
    """The rows of the claims table: the path's size, NNBC's 6 mm, JMPI fails, NNBC better than JMPI."""
    rows: list[list[str]] = []
    size_measured = _size(measured) if measured is not None else "-"
    if measured is not None:
        match = (
            "the formula, not the text"
            if formula is not None and np.allclose(measured, formula, atol=2e-3)
            else "see below"
        )
        rows.append(
            [
                "Path size",
                "0.8 x 0.8 x 0.2 m (text); its formula gives " + (_size(formula) if formula is not None else "-"),
                f"{size_measured} (extent of r_d)",
                f"ours follows {match}",
            ]
        )
    for dyn in modes:
        text, verdict = _claim_nnbc(result, nnbc, dyn)
        rows.append([f"NNBC max error <= 6 mm ({dyn})", "not more than 0.006 m", text, verdict])
    for dyn in modes:
        text, verdict = _claim_jmpi(result, nnbc, dyn)
        rows.append([f"JMPI fails ({dyn})", "apparently fails to fulfil the task (Fig. 3)", text, verdict])
    for dyn in modes:
        a, b = _agg(result, nnbc, dyn), _agg(result, "jmpi", dyn)
        if a and b and a["max_error_m"]["median"] is not None and b["max_error_m"]["median"] is not None:
            na, nb = a["max_error_m"]["median"], b["max_error_m"]["median"]
            rows.append(
                [
                    f"NNBC better than JMPI ({dyn})",
                    '"efficacy and superiority of the proposed NNBC"',
                    f"median max error NNBC {_mm(na, nnbc)} vs JMPI {_mm(nb)}",
                    "holds" if na < nb else "does not hold",
                ]
            )
    return rows


def _per_seed_table(result, specs, nnbc: str, oracle: str, modes) -> str:
    """Max error per seed (mm) of NNBC, JMPI, CLIK, the oracle and the ceiling, per mode."""
    cfg = result.results["config"]
    shown = [p for p in (nnbc, "jmpi", spec_of(specs, "clik"), oracle, spec_of(specs, "qp-oracle")) if p]
    header = ["seed"] + [f"{p} ({d})" for d in modes for p in shown]
    per_seed = []
    for k in range(cfg["episodes"]):
        row = [str(cfg["seed"] + k)]
        for d in modes:
            for p in shown:
                rec = next(
                    (r for r in result.episodes if r["policy"] == p and r["dynamics"] == d and r["episode"] == k), None
                )
                row.append("-" if rec is None else format_mm(rec.get("max_error_m"), p))
        per_seed.append(row)
    return markdown_table(header, per_seed)


def _pct(result) -> str:
    """The model error of the run's episodes as a percentage (e.g. "5%")."""
    values = {r.get("model_error") for r in result.episodes if r.get("model_error") is not None}
    return ", ".join(f"{v * 100:g}%" for v in sorted(values)) or "unknown"


def _best_other(result, dyn: str, exclude: tuple) -> tuple[str, float] | None:
    """(policy, median max error) of the best policy not in `exclude` in this mode, if any."""
    cands = [
        (a["policy"], a["max_error_m"]["median"])
        for a in result.aggregate
        if a["dynamics"] == dyn and a["policy"] not in exclude and a["max_error_m"]["median"] is not None
    ]
    return min(cands, key=lambda c: c[1]) if cands else None


def _differences(result, nnbc, modes, measured, formula, oracle: str = "oracle") -> list[str]:
    """The "Where we differ, and why" bullets: the path's size, NNBC and JMPI per mode, the comparison, and
    the dynamics."""
    out = []
    if measured is not None and formula is not None:
        out.append(
            f"* **Path size.** The paper's text says 0.8 m x 0.8 m x 0.2 m, but its own formula (r_dY = l cos(pi/6) "
            f"sin(...), r_dZ = l sin(pi/6) sin(...), l = 0.4 m) spans 2l x 2l cos(pi/6) x 2l sin(pi/6) = "
            f"{_size(formula)}. We implement the formula; the measured extent of the desired path is "
            f"{_size(measured)}. The text's y and z sizes are inconsistent with the formula (0.8 would need no tilt "
            f"in y, 0.2 half of the z span)."
        )
    out += [line for dyn in modes if (line := _nnbc_difference(result, nnbc, dyn, oracle))]
    out += [line for dyn in modes if (line := _jmpi_difference(result, dyn))]
    out += [line for dyn in modes if (line := _comparison_difference(result, nnbc, dyn))]
    if "physics" in modes and "kinematic" in modes:
        k, p = _agg(result, nnbc, "kinematic"), _agg(result, nnbc, "physics")
        if k and p and k["max_error_m"]["median"] is not None and p["max_error_m"]["median"] is not None:
            out.append(
                f"* **Dynamics.** The paper's model is kinematic (commanded speeds are taken as realised "
                f"exactly), like our kinematic mode. "
                f"NNBC's median max error is {_mm(k['max_error_m']['median'], nnbc)} in our kinematic mode and "
                f"{_mm(p['max_error_m']['median'], nnbc)} with PyBullet contact dynamics."
            )
    return out


def _nnbc_difference(result, nnbc: str, dyn: str, oracle: str) -> str | None:
    """NNBC against the paper's 6 mm in mode `dyn`, and how much of its error the oracle explains."""
    a = _agg(result, nnbc, dyn)
    errs = _errs(result, nnbc, dyn)
    if a is None or not errs:
        return None
    n_ok = sum(e <= PAPER_MAX_ERROR for e in errs)
    med = a["max_error_m"]["median"]
    if n_ok == a["n"]:
        return f"* **NNBC, {dyn}:** within 6 mm in every seed (median {_mm(med, nnbc)}), as the paper says."
    line = (
        f"* **NNBC, {dyn}:** above 6 mm in {a['n'] - n_ok}/{a['n']} seeds (median {_mm(med, nnbc)}, worst "
        f"{_mm(max(errs), nnbc)})."
    )
    if a.get("n_tipped_over"):
        line += (
            f" In {a['n_tipped_over']} of them the platform tipped over (roll or pitch > 30 deg) and the "
            f"episode ended early."
        )
    o = _agg(result, oracle, dyn)
    if o is not None and o["max_error_m"]["median"] is not None:
        line += _oracle_explanation(result, nnbc, dyn, oracle, med, o)
    return line


def _oracle_explanation(result, nnbc: str, dyn: str, oracle: str, med: float, o: dict) -> str:
    """What the oracle (the same law with the true Jacobian) says about NNBC's error in mode `dyn`."""
    om = o["max_error_m"]["median"]
    if om <= PAPER_MAX_ERROR:
        return (
            f" The oracle (true Jacobian, same loop) stays at a median {_mm(om)}, so the excess is the "
            f"cost of estimating J online. The paper's J_hat(0) is a matrix that did not survive in its "
            f"text; we start model-free from a short probe whose steps count in the error, and we run "
            f"the paper's continuous-time equations at 100 Hz."
        )
    limited = [
        r
        for r in result.episodes
        if r["policy"] == oracle and r["dynamics"] == dyn and r["status"] == "ok" and r.get("joint_limit_hits", 0) > 0
    ]
    text = (
        f" The oracle, the same law (eq. (10)) given the true robot's Jacobian, reaches a "
        f"median {_mm(om)} too, so that much is not the cost of estimating J: it runs into a joint "
        f"limit in {len(limited)}/{o['n']} seeds. The circle goes round the shoulder axis, so joint "
        f"1 plus the platform's yaw must turn a full 360 deg; eq. (10)'s minimum-norm solution gives "
        f"most of that turn to joint 1, which stops at the PUMA 560's +-160 deg late in the circle, "
        f"and the law has no way to hand the turn to the platform. The rest "
        f"({_mm(max(med - om, 0.0), nnbc)} of the median) is the cost of the online estimate."
    )
    best = _best_other(result, dyn, exclude=(nnbc, oracle, "jmpi"))
    if best is not None and best[1] < PAPER_MAX_ERROR:
        text += (
            f" The task itself allows much less: `{best[0]}` reaches a median {_mm(best[1], best[0])} without a model."
        )
    return text


def _jmpi_difference(result, dyn: str) -> str | None:
    """JMPI against the 6 mm criterion in mode `dyn`."""
    a = _agg(result, "jmpi", dyn)
    errs = _errs(result, "jmpi", dyn)
    if a is None or not errs:
        return None
    n_fail = sum(e > PAPER_MAX_ERROR for e in errs)
    if n_fail == len(errs):
        return (
            f"* **JMPI, {dyn}:** fails the 6 mm criterion in every seed (median {_mm(a['max_error_m']['median'])}): "
            f"open loop on the nominal model, its error accumulates with the {_pct(result)} model error, as the paper "
            f"argues. How badly it fails depends on how wrong the model is, which the paper does not state."
        )
    return (
        f"* **JMPI, {dyn}:** within 6 mm in {len(errs) - n_fail}/{len(errs)} seeds: with a true robot "
        f"close to the nominal one the open-loop error stays small; the paper's unknown model error is "
        f"not stated, ours is {_pct(result)} relative std per length."
    )


def _comparison_difference(result, nnbc: str, dyn: str) -> str | None:
    """The superiority claim in mode `dyn`, when NNBC does not beat JMPI."""
    a, b = _agg(result, nnbc, dyn), _agg(result, "jmpi", dyn)
    if not (a and b and a["max_error_m"]["median"] is not None and b["max_error_m"]["median"] is not None):
        return None
    if a["max_error_m"]["median"] < b["max_error_m"]["median"]:
        return None
    return (
        f"* **NNBC vs JMPI, {dyn}:** here the paper's NNBC does worse than JMPI (median max error "
        f"{_mm(a['max_error_m']['median'], nnbc)} vs {_mm(b['max_error_m']['median'])}), so the paper's "
        f"superiority claim is not reproduced in this mode."
    )


def _success(result, policy: str, dyn: str) -> tuple[int, int] | None:
    """(episodes within 6 mm, episodes) of `policy` in mode `dyn`, or None when it did not run."""
    a = _agg(result, policy, dyn)
    if a is None:
        return None
    return sum(e <= PAPER_MAX_ERROR for e in _errs(result, policy, dyn)), a["n"]


def _baselines(result, specs, nnbc: str, oracle: str, modes) -> list[str]:
    """What `clik` (the nominal model with feedback) and `qp-oracle` (the known-model ceiling with joint
    limits) say about the paper's claims; says so when they were not run."""
    clik, ceiling = spec_of(specs, "clik"), spec_of(specs, "qp-oracle")
    out = []
    if clik is None:
        out.append(
            "* **`clik` was not run** (not registered in this install). It is eq. (10) on the *nominal* model: "
            'the closed-loop controller an engineer would run. Without it, "JMPI fails" only shows that open '
            "loop fails, not that a model-free controller beats a model-based one."
        )
    else:
        for dyn in modes:
            c, j, m = _success(result, clik, dyn), _success(result, "jmpi", dyn), _success(result, nnbc, dyn)
            ca = _agg(result, clik, dyn)
            if c is None or j is None or m is None or ca is None:
                continue
            med = format_mm(ca["max_error_m"]["median"], clik, 1) + " mm"
            line = (
                f"* **`{clik}` vs JMPI, {dyn}:** the same nominal model as JMPI with eq. (10)'s feedback term (its default gain) is within "
                f"6 mm in {c[0]}/{c[1]} seeds (median {med}); JMPI in {j[0]}/{j[1]}, `{nnbc}` in {m[0]}/{m[1]}."
            )
            if c[0] > j[0]:
                line += (
                    " So JMPI's failure is the failure of open loop, not of knowing only the nominal model: the "
                    'paper\'s comparison cannot separate "model-free" from "feedback".'
                )
            if c[0] >= m[0]:
                line += (
                    " At this model error the practitioner's baseline does at least as well as the paper's NNBC, "
                    'so the paper\'s "superiority" claim holds against JMPI only.'
                )
            else:
                line += f" Here `{nnbc}` beats it: learning J pays off at this model error."
            out.append(line)
    if ceiling is None:
        out.append(
            "* **`qp-oracle` was not run** (not registered in this install). It is the known-model ceiling: the "
            "true robot's Jacobian in a QP that respects joint limits. Without it, `oracle` (eq. (10) on the "
            "true robot, which runs into joint 1's stop) understates what a controller can reach on this task."
        )
    else:
        for dyn in modes:
            q, o = _success(result, ceiling, dyn), _success(result, oracle, dyn)
            qa = _agg(result, ceiling, dyn)
            if q is None or qa is None:
                continue
            line = (
                f"* **`{ceiling}`, {dyn}:** within 6 mm in {q[0]}/{q[1]} seeds, median max error "
                f"{format_mm(qa['max_error_m']['median'], ceiling, 2)} mm: what knowing the robot allows on this task"
            )
            if o is not None:
                line += f" (eq. (10) with the same knowledge, `{oracle}`: {o[0]}/{o[1]})"
            na = _agg(result, nnbc, dyn)
            if na is not None and na["max_error_m"]["median"] is not None and qa["max_error_m"]["median"]:
                ratio = na["max_error_m"]["median"] / qa["max_error_m"]["median"]
                line += f". `{nnbc}`'s median is {format_value(ratio, nnbc, 1)} times it"
            out.append(line + ".")
    if is_chaotic(nnbc):
        out.append(f"* {CHAOTIC_NOTE}.")
    return out
