"""`mobman-eval bench`: the benchmark protocol v1 in one command (tasks x conditions x controllers x seeds).

* `config`: the protocol as data (`ROBOTS`, `TASKS`, `CONDITIONS`, `DEFAULT_CONDITIONS`, `BenchConfig`).
* `run`: `run_bench`, one resumable sweep (`eval.sweep`) per condition under `DIR/conditions/<name>/`, then the
  scorecard. A bench is a sweep with a fixed grid of conditions: no second runner, the same journal, the same
  resume rules, the same local and Ray executors.
* `scorecard`: scorecard.json / scorecard.md / plots and the README block generated from a scorecard.
* `chaos`: the measurement behind `eval.output.precision` (how many digits a controller's results have).

Layer 7 of eval (beside `paper`): imports `sweep`, `output`, `execution`, `metrics`, `rollout`, `errors`.
"""
