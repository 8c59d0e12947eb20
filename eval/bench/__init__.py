"""`mobman-eval bench`: the benchmark protocol v2 in one command (per condition of a track: its robots x tasks x
controllers x seeds).

* `config`: the protocol as data (`ROBOTS`, `TASKS`, `CONDITIONS` with their tracks, `DEFAULT_CONDITIONS`,
  the held-out digest and commit, `BenchConfig`).
* `run`: `run_bench`, one resumable sweep (`eval.sweep`) per condition under `DIR/conditions/<name>/`, then the
  scorecard. A bench is a sweep with a fixed grid of conditions: no second runner, the same journal, the same
  resume rules, the same local and Ray executors.
* `preflight`: every controller spec built on every cell's env before any episode; a spec that cannot run some
  cells is refused naming them, the reason and the `--robots` / `--tasks` / `--conditions` that leave them out.
* `scorecard`: scorecard.json / scorecard.md / plots and the README block generated from a scorecard.
* `against`: `--against DIR`, a new controller beside a committed scorecard's baselines (a sample re-run bit for
  bit first).
* `chaos`: the measurement behind `eval.output.precision` (how many digits a controller's results have).

Layer 8 of eval (beside `paper`): imports `sweep`, `output`, `execution`, `checks`, `metrics`,
`rollout`, `errors`.
"""
