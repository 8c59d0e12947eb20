"""Issue 28's targets for `nnbc-plus`, read from a committed dev-track scorecard (reported seeds).

    python docs/results/nnbc-plus-v4/targets.py docs/results/bench-v2-dev/scorecard.json > docs/results/nnbc-plus-v4/targets.md

Each target with the figure measured: success and clean success on every dev cell (condition x robot, tasks
pooled), the commands' acceleration RMS at `default` against `qp`'s, the max-error IQM at `default` against
`qp-oracle`'s, and the median max error under sensor noise (`noise`) against `qp`'s. Medians and IQMs are pooled
over the condition's episodes (the scorecard's `pooled` rows).
"""

from __future__ import annotations

import sys
from collections import defaultdict

from eval.bench.scorecard import load_scorecard


def main(path: str, policy: str = "nnbc-plus") -> str:
    s = load_scorecard(path)  # the one reader: a compacted scorecard.json.xz is read as its scorecard.json
    rows = [r for r in s["rows"] if r["track"] == "dev" and not r["condition"].startswith("ladder")]
    cells: dict[tuple[str, str], list[int]] = defaultdict(lambda: [0, 0, 0])
    for r in rows:
        if r["policy"] != policy:
            continue
        robot = r["env"].split("-")[0].removeprefix("Wheeled")
        c = cells[(r["condition"], robot)]
        c[0] += round(r["success_rate"] * r["n"])
        c[1] += round(r["clean_success_rate"] * r["n"])
        c[2] += r["n"]
    out = [
        f"# `{policy}` against issue 28's targets",
        "",
        f"From the dev-track scorecard recorded at git {s['git'][:7]}.",
    ]
    out += ["", "## Targets", ""]
    targets = len(out)
    out += ["", "## Dev cells", "", "| dev cell | success | clean success |", "|---|---|---|"]
    low: list[str] = []
    failing: list[str] = []
    for (cond, robot), (ok, clean, n) in sorted(cells.items()):
        out.append(f"| {cond}, {robot} | {ok}/{n} | {clean}/{n} |")
        if ok < 0.95 * n or clean < 0.95 * n:
            low.append(f"{cond}/{robot}")
        if ok < 0.95 * n:
            failing.append(f"{cond}/{robot} {ok}/{n}")
    below = f"{len(low)} of {len(cells)}" + (f" ({', '.join(low)})" if low else "")
    lines = [
        f"* dev cells (condition x robot, tasks pooled) below 95% success or clean success: {below}",
        f"* of those, below 95% success: {len(failing)}" + (f" ({', '.join(failing)})" if failing else ""),
    ]

    def pooled(cond: str, pol: str) -> dict:
        (row,) = [r for r in s["pooled"] if r["condition"] == cond and r["policy"] == pol]
        return row

    def ratio(cond: str, key: str, stat: str, other: str) -> tuple[float, float]:
        return pooled(cond, policy)[key][stat], pooled(cond, other)[key][stat]

    a, q = ratio("default", "cmd_accel_rms", "median", "qp")
    lines.append(
        f"* commands' acceleration RMS at `default` (median over its episodes): {a:.3g} rad/s^2 against `qp`'s "
        f"{q:.3g}: {a / q:.3g}x (target <= 3x)"
    )
    i, o = ratio("default", "max_error_m", "iqm", "qp-oracle")
    lines.append(
        f"* max-error IQM at `default`: {i * 1e3:.3g} mm against `qp-oracle`'s {o * 1e3:.3g} mm: {i / o:.3g}x "
        "(target <= 3x)"
    )
    m, mq = ratio("noise", "max_error_m", "median", "qp")
    lines.append(
        f"* median max error under `noise`: {m * 1e3:.3g} mm against `qp`'s {mq * 1e3:.3g} mm (target: at or below)"
    )
    out[targets:targets] = lines
    return "\n".join(out) + "\n"


if __name__ == "__main__":
    sys.stdout.write(main(*sys.argv[1:]))
