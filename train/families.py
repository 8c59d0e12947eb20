"""`mobman-train families`: agents trained with several seeds, scored as families over one bench's episodes.

```
mobman-train families runs/bench-s0 runs/bench-s1 runs/bench-s2 --family ppo-dev=sb3:R/ppo-dev-s0,sb3:R/ppo-dev-s1,sb3:R/ppo-dev-s2 \
    --out docs/results/rl-v3
```

Reads the episode records of `mobman-eval bench` folders (`results.json`) in which every member of a family ran
on the same cells and seeds, and writes `families.json` and `families.md`: per family the final-table row of
`train.report_stats.family_row` over (training seeds x episodes), i.e. the IQM of the max error with rliable's
stratified bootstrap interval over training seeds (episodes as strata) and the success rate with the same
bootstrap, each seed's own figures, and the median-seed member (`median_run`: the seed whose IQM max error is
the median of the family's), which is the one to ship. Episodes are keyed by (condition, env, seed).
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from train.report_stats import family_row, median_run


def _episodes(records: Sequence[dict], spec: str) -> list[dict]:
    rows = [r for r in records if r.get("policy") == spec]
    if not rows:
        known = sorted({str(r.get("policy")) for r in records})
        raise ValueError(f"{spec!r} ran no episode of this bench; its policies: {known}")
    rows.sort(key=lambda r: (str(r.get("condition")), str(r.get("env")), int(r["seed"])))
    # family_row keys episodes by "seed": one key per (condition, env, seed) cell episode
    return [{**r, "seed": f"{r.get('condition')}|{r.get('env')}|{r['seed']}"} for r in rows]


def families(records: Sequence[dict], members: Mapping[str, Sequence[str]]) -> dict[str, Any]:
    """The family rows and median-seed members of `members` (family -> the specs of its seeds, in seed order)."""
    out: dict[str, Any] = {}
    for name, specs in members.items():
        runs = [{"name": spec, "seed": k, "episodes": _episodes(records, spec)} for k, spec in enumerate(specs)]
        row = family_row(name, runs)
        row["seeds"] = list(specs)
        median = median_run(runs, key=lambda r: row["max_error_m"]["per_seed_iqm"][r["seed"]])
        out[name] = {**row, "median_seed_member": median["name"]}
    return out


def _label(spec: str) -> str:
    """A member as the tables show it: an `sb3:` run folder by its name (families.json keeps the whole spec)."""
    return Path(spec[4:]).name if spec.startswith("sb3:") else spec


def _pct(x: float) -> str:
    return f"{x * 100:.0f}%"


def markdown(fams: Mapping[str, Any]) -> str:
    """The families as a Markdown table, then each family's seeds."""
    lines = [
        "## Families",
        "",
        "| family | seeds x episodes | failed | success [95% CI over seeds] | max err IQM [95% CI over seeds] (mm) | "
        "shipped (median seed) |",
        "|---|---|---|---|---|---|",
    ]
    for name, f in fams.items():
        ci = f["success_rate_ci95"]
        me = f["max_error_m"]
        mci = me["iqm_ci95"]
        rate = _pct(f["success_rate"]) + (f" [{_pct(ci[0])}-{_pct(ci[1])}]" if ci else "")
        iqm = f"{me['iqm'] * 1e3:.2f}" + (f" [{mci[0] * 1e3:.2f}-{mci[1] * 1e3:.2f}]" if mci else "")
        n_eps = f["n_episodes"] // f["n_seeds"]
        lines.append(
            f"| {name} | {f['n_seeds']} x {n_eps} | {f['n_failed']} | {rate} | {iqm} | `{_label(f['median_seed_member'])}` |"
        )
    lines += ["", "## Seeds", "", "Per seed (success, max err IQM in mm):", ""]
    for name, f in fams.items():
        per = zip(f["seeds"], f["per_seed_success_rate"], f["max_error_m"]["per_seed_iqm"], strict=True)
        lines.append(f"* {name}: " + "; ".join(f"`{_label(s)}` {_pct(r)}, {i * 1e3:.2f}" for s, r, i in per))
    return "\n".join(lines) + "\n"


def write(bench_dirs: Sequence[str | Path], members: Mapping[str, Sequence[str]], out: str | Path) -> dict[str, Any]:
    """Read each `bench_dir/results.json` (one bench per seed is fine: the same cells and seeds), write
    `families.json` and `families.md` into `out`; the families."""
    from eval.output.files import atomic_write_json
    from eval.output.results import load_results

    records = [e for d in bench_dirs for e in load_results(Path(d) / "results.json")["episodes"]]
    fams = families(records, members)
    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    source = {"benches": [str(d) for d in bench_dirs], "members": {k: list(v) for k, v in members.items()}}
    atomic_write_json(folder / "families.json", {"source": source, "families": fams})
    (folder / "families.md").write_text(markdown(fams), encoding="utf-8")
    return fams


def parse_family(text: str) -> tuple[str, list[str]]:
    """NAME=SPEC,SPEC,... (a family and its seeds' specs, in seed order)."""
    name, sep, specs = text.partition("=")
    members = [s for s in specs.split(",") if s]
    if not sep or not name or len(members) < 1:
        raise ValueError(f"--family {text!r}: expected NAME=SPEC[,SPEC...], e.g. ppo-dev=sb3:runs/a,sb3:runs/b")
    return name, members


def main(bench_dirs: Sequence[str], family_texts: Sequence[str], out: str) -> int:
    members = dict(parse_family(t) for t in family_texts)
    fams = write(bench_dirs, members, out)
    print(markdown(fams) + f"written to {out}")
    print(json.dumps({k: v["median_seed_member"] for k, v in fams.items()}))
    return 0
