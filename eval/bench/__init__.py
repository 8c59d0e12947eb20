"""`mobman-eval bench`: the benchmark protocol v2 in one command (per condition of a track: its robots x tasks x
controllers x seeds).

* `config`: `BenchConfig` and the tracks' default conditions over the one conditions table (`eval.conditions`:
  `ROBOTS`, `TASKS`, `CONDITIONS` with their tracks, the held-out digest and commit).
* `run`: `run_bench`, one resumable grid (`eval.sweep.run.run_grid`, as a sweep's) over every condition into one
  journal and one results file in `DIR`, each record naming its condition, then the scorecard: no second runner,
  the same resume rules, the same local and Ray executors.
* `preflight`: every controller spec built on every cell's env before any episode; a spec that cannot run some
  cells is refused naming them, the reason and the `--robots` / `--tasks` / `--conditions` that leave them out.
* `scorecard`: scorecard.json / scorecard.md / plots and the README block generated from a scorecard.
* `against`: `--against DIR`, a new controller beside a committed scorecard's baselines (a sample re-run bit for
  bit first).
* `chaos`: the measurement behind `eval.output.precision` (how many digits a controller's results have).

Layer 8 of eval (beside `paper`): imports `sweep`, `output`, `execution`, `checks`, `metrics`,
`rollout`, `errors`.
"""
