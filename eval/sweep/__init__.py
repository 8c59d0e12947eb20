"""eval.sweep: `mobman-eval sweep --config sweep.yaml`: a grid of episodes, one tidy results table, summary plots; resumable.

The grid (`eval.sweep.config`): every (env, dynamics, model_error, obs_noise, policy, seed) is one episode, run
by the same executors as `mobman-eval run` (`--workers N` local processes or `--backend ray`, kinematic
episodes batched up to `--batch-size` per condition and policy, any seeds), so a sweep episode equals the `run`
episode of the same settings. A batch's records reach the journal together, when the batch ends; an interrupted
batch runs again whole on resuming.

Output directory (default `runs/sweep-<config file stem>`, so running the same command again resumes):

| file | content |
|---|---|
| `episodes.jsonl` | the journal: one complete episode record per line, appended (one `write`) as each ends |
| `results.json` | schema 2 like `mobman-eval run`: config, versions, git, episodes (grid order), aggregate |
| `results.csv` | the tidy table: one row per episode, the columns of `run`'s results.csv |
| `aggregate.csv` | per (env, policy, dynamics, model_error, obs_noise): n, failures, success rate, error stats |
| `summary.md` | success rate and max error per policy and condition, in mm |
| `config.json` | the resolved sweep (grid, env_kwargs, tolerance) and how it last ran |
| `plots/<env>_<dynamics>_vs_<variable>.png` | success rate and max error vs model_error or obs_noise, per policy |

**Resuming.** An episode is identified by (env, policy, seed, dynamics, model_error, obs_noise). Episodes with a
record in the journal are skipped; the others run, in grid order. The journal is append-only and written by
this process alone (the workers send records back): a record is either complete or, if the process was
killed in the middle of its line, a torn last line that the next run drops (and runs that episode again). The
table files are rebuilt from the journal, in grid order, after every run and written atomically, so a sweep
interrupted at any point and run again gives the same table as one uninterrupted run (timing and pid fields
aside). `--max-episodes N` runs at most N new episodes (a job that must fit a time slot). Episodes that
produced no result at all (their worker process died, their Ray task failed twice) are in the table as failed
but not in the journal, so the next run tries them again; episodes that crashed inside the rollout are results
(status failed, traceback) and are skipped unless `--retry-failed`. The grid may grow between runs (more seeds,
policies, noise levels); `env_kwargs`, `tolerance` and `settle_time` may not change (start a new --out), nor
the code: every record carries the hash of the code that ran it, and a journal of other code is refused (use
another --out, or `--rerun-changed` to run those episodes again; `eval.grid.same_code`).

Modules: `config` (the YAML file -> `SweepConfig`), `run`
(`run_sweep`), `report` (aggregate.csv, summary.md, the console summary), `plots`; the append-only episode
journal is `eval.output.journal` (a run keeps one too).

May import: `eval.errors`, `eval.config`, `eval.metrics`, `eval.rollout`, `eval.checks`, `eval.execution`,
`eval.output`; never `eval.cli`.
"""
