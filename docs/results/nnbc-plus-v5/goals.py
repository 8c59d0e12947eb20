"""Issue 38's goals for `nnbc-plus` (v5, v5.1) and `nnbc-plus-wb`, read from a committed dev-track scorecard (reported seeds).

    python docs/results/nnbc-plus-v5/goals.py docs/results/bench-v3-dev/scorecard.json.xz docs/results/bench-v3-heldout-0.4/scorecard.json.xz > docs/results/nnbc-plus-v5/goals.md

Each goal with the figure measured, over protocol v3's dev track (v2's dev conditions, the ladder, v2's held-out
conditions): the commands' acceleration RMS median at `default` against `qp`'s (goal <= 3x); the max-error IQM
at `default` against the cell's reference, the better of `mpc-oracle` and `qp-oracle` (goal <= 3x; against
`qp-oracle` alone too); success and clean success in every dev cell, condition x robot with its tasks pooled
(goal >= 95%); and "never diverge": the median max error of every cell where the reference tracks (>= 95%) under
20 mm. With a held-out scorecard (optional second argument), the held-out goals too: pooled success over the
track against the better reference's (goal >= 90% of it), and "never diverge" per held-out condition (its robots
and tasks pooled). Figures are the scorecards' (`pooled` rows per condition, `by_robot` rows per cell); nothing is typed.
"""

from __future__ import annotations

import sys

from eval.bench.scorecard import load_scorecard

POLICIES = ("nnbc-plus", "nnbc-plus-wb")
REFERENCES = ("mpc-oracle", "qp-oracle")


def _fmt(x: float) -> str:
    return f"{x:.3g}"


def _heldout_rows(path: str) -> tuple[list[str], list[str]]:
    """The held-out goals' table cells per policy: success against the reference's, and never diverge."""
    sc = load_scorecard(path)
    track = {r["policy"]: r for r in sc["tracks"]}
    pooled = {(r["condition"], r["policy"]): r for r in sc["pooled"]}
    conds = list(dict.fromkeys(r["condition"] for r in sc["pooled"]))
    ref = max(REFERENCES, key=lambda q: track[q]["success_rate"])
    ok, div = [], []
    for pol in POLICIES:
        s, rs = track[pol]["success_rate"], track[ref]["success_rate"]
        ok.append(f"{s:.0%} = {s / rs:.0%} of {ref}'s {rs:.0%}")
        diverged = [
            f"{c} {_fmt(1e3 * pooled[(c, pol)]['max_error_m']['median'])} mm"
            for c in conds
            if any(pooled[(c, q)]["success_rate"] >= 0.95 for q in REFERENCES)
            and pooled[(c, pol)]["max_error_m"]["median"] >= 0.020
        ]
        div.append(
            f"{len(diverged)} of {len(conds)} conditions over 20 mm" + (f": {', '.join(diverged)}" if diverged else "")
        )
    return ok, div


def main(path: str, heldout: str | None = None) -> str:
    sc = load_scorecard(path)
    pooled = {(r["condition"], r["policy"]): r for r in sc["pooled"]}
    cells = {(r["condition"], r["robot"], r["policy"]): r for r in sc["by_robot"]}
    keys = sorted(
        {(c, rb) for c, rb, _ in cells},
        key=lambda k: (list(dict.fromkeys(r["condition"] for r in sc["pooled"])).index(k[0]), k[1]),
    )
    out = [
        "# `nnbc-plus` against issue 38's goals",
        "",
        f"The law as the dev-track scorecard recorded it at git {str(sc['git'])[:7]} (protocol v{sc['protocol']['version']}, "
        f"seeds from {sc['protocol']['seed_start']}), by `docs/results/nnbc-plus-v5/goals.py`.",
        "",
        "## Goals",
        "",
        "| goal | " + " | ".join(f"`{p}`" for p in POLICIES) + " |",
        "|---|" + "---|" * len(POLICIES),
    ]
    qp_acc = pooled[("default", "qp")]["cmd_accel_rms"]["median"]
    refs = {r: pooled[("default", r)]["max_error_m"]["iqm"] for r in REFERENCES}
    best = min(refs, key=refs.get)
    row_acc, row_ref, row_qpo, row_cells, row_div = [], [], [], [], []
    below: dict[str, list[str]] = {}
    for pol in POLICIES:
        d = pooled[("default", pol)]
        acc = d["cmd_accel_rms"]["median"]
        row_acc.append(f"{_fmt(acc)} rad/s^2 = {acc / qp_acc:.1f}x qp's {_fmt(qp_acc)}")
        iqm = d["max_error_m"]["iqm"]
        row_ref.append(f"{_fmt(1e3 * iqm)} mm = {iqm / refs[best]:.1f}x {best}'s {_fmt(1e3 * refs[best])} mm")
        qpo = refs["qp-oracle"]
        row_qpo.append(f"{iqm / qpo:.1f}x qp-oracle's {_fmt(1e3 * qpo)} mm")
        low, diverged = [], []
        for cond, robot in keys:
            r = cells.get((cond, robot, pol))
            if r is None:
                continue
            if min(r["success_rate"], r["clean_success_rate"]) < 0.95:
                low.append(f"{cond}/{robot} {r['success_rate']:.0%}/{r['clean_success_rate']:.0%}")
            tracked = any(cells[(cond, robot, ref)]["success_rate"] >= 0.95 for ref in REFERENCES)
            if tracked and r["max_error_m"]["median"] >= 0.020:
                diverged.append(f"{cond}/{robot} {_fmt(1e3 * r['max_error_m']['median'])} mm")
        n_cells = sum(1 for c, rb in keys if (c, rb, pol) in cells)
        row_cells.append(f"{n_cells - len(low)} of {n_cells} cells")
        row_div.append(f"{len(diverged)} cells over 20 mm" + (f": {', '.join(diverged)}" if diverged else ""))
        below[pol] = low
    out += [
        "| smooth: cmd accel RMS median at default <= 3x qp's | " + " | ".join(row_acc) + " |",
        "| accurate: max-error IQM at default <= 3x the reference's | " + " | ".join(row_ref) + " |",
        "| (against qp-oracle alone) | " + " | ".join(row_qpo) + " |",
        "| robust: >= 95% success and clean success per dev cell | " + " | ".join(row_cells) + " |",
        "| never diverge: median max error < 20 mm where the reference tracks | " + " | ".join(row_div) + " |",
    ]
    if heldout is not None:
        h_ok, h_div = _heldout_rows(heldout)
        out += [
            "| held out: success >= 90% of the reference law's (pooled over the draw) | " + " | ".join(h_ok) + " |",
            "| held out: median max error < 20 mm where the reference tracks | " + " | ".join(h_div) + " |",
        ]
    out += [
        "",
        "## Cells below 95%",
        "",
        "Success / clean success of each dev cell (condition / robot, its tasks pooled) below 95% in either:",
        "",
    ]
    for pol in POLICIES:
        out += [f"* `{pol}` ({len(below[pol])}): " + "; ".join(below[pol]), ""]
    return "\n".join(out)


if __name__ == "__main__":
    sys.stdout.write(main(*sys.argv[1:3]))
