"""The bench's pre-flight: every controller spec built on the env of every cell (robot x task x condition) before
any episode runs, so a spec that cannot run somewhere (an agent with 8 actions on the 9-actuator Panda) is
refused at once, naming the spec, the cells, the reason and the `--robots` / `--tasks` / `--conditions` that
leave those cells out, instead of after the other controllers' episodes and behind a warning per env.

Building is cheap (a built-in in microseconds, an `sb3:` agent in ~0.06 s once torch is loaded), so every cell
is checked as its episodes will make it (`eval.checks.PolicyCheck`); the grid's own checks then skip the specs
checked here.
"""

from __future__ import annotations

from eval.bench.config import CONDITIONS, ROBOTS, TASKS, BenchConfig
from eval.checks import PolicyCheck, build_env

#: a cell of the bench: (condition, robot, task)
Cell = tuple[str, str, str]
#: the axes a fix may name: the option that restricts each, its index in a `Cell` and its names in order; tried
#: in this order
AXES: tuple[tuple[str, int, list[str]], ...] = (
    ("robots", 1, list(ROBOTS)),
    ("tasks", 2, list(TASKS)),
    ("conditions", 0, list(CONDITIONS)),
)


def check_cells(cfg: BenchConfig) -> list[str]:
    """Build each of `cfg.policies` (a resolved bench) on every cell's env, as the episodes build it;
    EvalError for the first spec that cannot run on some cell. Returns one line per spec whose building warned
    (e.g. an agent evaluated off the env it was trained on), for the caller to print."""
    assert cfg.policies is not None and cfg.conditions is not None
    check = PolicyCheck(cfg.policies, cfg.seed_start)
    for name in cfg.conditions:
        c = CONDITIONS[name]
        robots, tasks = cfg.condition_robots(name), cfg.condition_tasks(name)
        for env_id, (robot, task) in zip(cfg.env_ids(name), [(r, t) for r in robots for t in tasks], strict=True):
            env = build_env(env_id, c.dynamics, c.model_error, c.obs_noise, cfg.condition_kwargs(name))
            try:
                check.on(env, (name, robot, task))
            finally:
                env.close()
    check.refuse(describe, lambda cells: fix(cells, check.cells))
    return check.warning_lines()


def _unique(values: list[str], order: list[str]) -> list[str]:
    return sorted(set(values), key=order.index)


def describe(cells: list[Cell]) -> str:
    """The failing cells in words: a product "robot(s) A x task(s) B in condition(s) C" when they are one, else
    the first few as robot/task (condition)."""
    conds = _unique([c for c, _, _ in cells], list(CONDITIONS))
    robots = _unique([r for _, r, _ in cells], list(ROBOTS))
    tasks = _unique([t for _, _, t in cells], list(TASKS))
    if len(cells) == len(conds) * len(robots) * len(tasks):
        return f"robot(s) {', '.join(robots)} x task(s) {', '.join(tasks)} in condition(s) {', '.join(conds)}"
    shown = ", ".join(f"{r}/{t} ({c})" for c, r, t in cells[:6])
    return shown + (f" and {len(cells) - 6} more" if len(cells) > 6 else "")


def fix(failing: list[Cell], checked: list[Cell]) -> str:
    """The option that leaves exactly the failing cells' robots (else tasks, else conditions) out, with the
    values that stay: e.g. "--robots puma,ur5,random-arm"."""
    bad = set(failing)
    for option, axis, order in AXES:
        out = {c[axis] for c in failing}
        keep = _unique([c[axis] for c in checked if c[axis] not in out], order)
        if keep and all((c in bad) == (c[axis] in out) for c in checked):
            return f"Leave those cells out with --{option} {','.join(keep)}, or leave the policy out."
    return "Leave those cells out with --robots, --tasks or --conditions, or leave the policy out."
