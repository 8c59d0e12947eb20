"""mobman-eval bench: the protocol table, config checks, a small bench end to end (files, resume, budget),
the scorecard and its README block, the statistics plots.

Benches here are 1 s kinematic circles (SHORT) on two tasks: they test the machinery, not controllers."""

from __future__ import annotations

import json

import pytest
from test_eval_helpers import SHORT

from eval.bench import config as BC
from eval.bench.run import run_bench, sweep_for
from eval.bench.scorecard import (
    README_BLOCK,
    load_scorecard,
    readme_markdown,
    render_readme,
    scorecard_markdown,
)
from eval.cli import main
from eval.errors import EvalError
from eval.metrics import SUCCESS_CURVE_TOLERANCES

SEED = 10_000


def _small(**kw) -> BC.BenchConfig:
    base = {
        "tasks": ("circle", "line"),
        "conditions": ("default", "wear20"),
        "policies": ("zero", "jmpi"),
        "seeds": 2,
        "env_kwargs": SHORT,
    }
    return BC.BenchConfig(**{**base, **kw})


# --- the protocol as data -----------------------------------------------------------------------------------


def test_default_controllers_are_the_registry():
    from policies.registry import KNOWN_POLICIES

    assert BC.default_policies() == tuple(KNOWN_POLICIES)  # grows with the registry
    assert "zero" in BC.default_policies() and "random" in BC.default_policies()  # the floors
    assert not [p for p in BC.default_policies() if ":" in p]  # no sb3:/module: forms


def test_default_conditions_are_those_this_env_can_build():
    cfg, notes = BC.BenchConfig().resolved()
    env_args = BC.env_arguments("WheeledPuma-Circle-v0")
    for name in BC.DEFAULT_CONDITIONS:
        can = all(k in env_args for k in BC.CONDITIONS[name].env_kwargs)
        assert (name in cfg.conditions) is can
        assert any(f"condition {name!r} left out" in n for n in notes) is not can
    assert cfg.policies == BC.default_policies() and cfg.seed_list == tuple(range(SEED, SEED + 20))
    assert BC.CONDITIONS["noise"].obs_noise == 0.001 and BC.CONDITIONS["noise"].env_kwargs == {"obs_noise_vel": 0.01}
    assert BC.CONDITIONS["wear20"].model_error == 0.2 and BC.CONDITIONS["physics"].dynamics == "physics"


def test_a_condition_the_env_cannot_build_is_refused_by_name(monkeypatch):
    ghost = BC.Condition("ghost", "needs an env argument no env has", env_kwargs={"no_such_argument": 1.0})
    monkeypatch.setitem(BC.CONDITIONS, "ghost", ghost)
    with pytest.raises(EvalError, match="condition 'ghost' needs the env argument.*no_such_argument"):
        _small(conditions=("default", "ghost")).resolved()


@pytest.mark.parametrize(
    "kw, match",
    [
        ({"tasks": ("circel",)}, "unknown task 'circel' \\(did you mean 'circle'\\?\\); known: circle, line"),
        ({"conditions": ("wear21",)}, "unknown condition 'wear21'.*known: default, wear20"),
        ({"robots": ("kuka",)}, "unknown robot 'kuka'; known: puma"),
        ({"tasks": ()}, "tasks is empty"),
        ({"tasks": ("line", "line")}, "tasks lists line more than once"),
        ({"policies": ("jmpi", "jmpi")}, "policies lists jmpi more than once"),
        ({"seeds": 0}, "seeds must be an integer >= 1"),
        ({"seeds": True}, "seeds must be an integer"),
        ({"tolerance": -1.0}, "tolerance must be a finite number > 0"),
        ({"env_kwargs": {"model_error": 0.1}}, "env_kwargs sets \\['model_error'\\]"),
    ],
)
def test_bad_bench_settings_are_named(kw, match):
    with pytest.raises(EvalError, match=match):
        _small(**kw).resolved()


def test_a_robot_without_env_ids_is_refused(monkeypatch):
    monkeypatch.setitem(BC.ROBOTS, "ghost", "WheeledGhost")
    with pytest.raises(EvalError, match="robot\\(s\\) ghost are not in this version of mobman_env.*available: puma"):
        _small(robots=("ghost",)).resolved()


def test_dev_seeds_get_a_note():
    _, notes = _small(seed_start=0).resolved()
    assert any("development results, not for reporting" in n for n in notes)


def test_a_condition_is_a_sweep_grid():
    cfg, _ = _small(conditions=("noise",)).resolved()
    sw = sweep_for(cfg, "noise")
    assert sw.envs == ("WheeledPuma-Circle-v0", "WheeledPuma-Line-v0")
    assert (sw.dynamics, sw.model_error, sw.obs_noise) == (("kinematic",), (0.05,), (0.001,))
    assert sw.env_kwargs == {**SHORT, "obs_noise_vel": 0.01} and sw.seeds == (SEED, SEED + 1)


# --- a bench end to end -------------------------------------------------------------------------------------


def _comparable(sc: dict) -> dict:
    drop = {"provenance", "wall_s", "git"}
    out = {k: v for k, v in sc.items() if k not in drop}
    for key in ("rows", "pooled"):
        out[key] = [{k: v for k, v in r.items() if not k.startswith("predict_us")} for r in sc[key]]
    return out


def test_bench_writes_a_scorecard_and_resumes(tmp_path):
    out = tmp_path / "bench"
    first = run_bench(_small(), out, progress=False, plots=True, max_episodes=5)
    assert (first.n_run, first.n_left) == (5, 11)  # the budget spans the conditions, in order
    assert first.scorecard["n_episodes"] == 5 and first.scorecard["n_expected"] == 16
    done = run_bench(_small(), out, progress=False, plots=True)
    assert (done.n_run, done.n_skipped, done.n_left) == (11, 5, 0)
    sc = load_scorecard(out / "scorecard.json")
    for name in ("bench.json", "scorecard.md", "plots/success_default.png", "plots/success_wear20.png"):
        assert (out / name).is_file(), name
    assert (out / "plots" / "error_vs_wear.png").is_file()  # two wear levels: 0.05 and 0.2
    for cond in ("default", "wear20"):
        assert json.loads((out / "conditions" / cond / "results.json").read_text())["schema"] == 2
    assert sc["schema"] == 2 and sc["protocol"]["seeds"] == [SEED, SEED + 1]
    assert len(sc["rows"]) == 2 * 2 * 2 and len(sc["pooled"]) == 2 * 2
    assert {(r["condition"], r["env"], r["policy"]) for r in sc["rows"]} == {
        (c, e, p)
        for c in ("default", "wear20")
        for e in ("WheeledPuma-Circle-v0", "WheeledPuma-Line-v0")
        for p in ("zero", "jmpi")
    }
    pooled = {(r["condition"], r["policy"]): r for r in sc["pooled"]}
    zero = pooled[("default", "zero")]
    assert zero["n"] == 4 and zero["success_rate"] == 0.0 and zero["success_rate_ci95"][0] == 0.0
    assert zero["max_error_m"]["iqm"] == pytest.approx(0.2, abs=1e-6)  # zero stays: the 0.1 m circle's diameter
    assert len(zero["success_curve"]) == len(SUCCESS_CURVE_TOLERANCES)
    assert sc["provenance"]["blas"] is not None and sc["statistics"]["bootstrap_resamples"] == 2000

    again = run_bench(_small(), out, progress=False, plots=False)  # nothing left: the same scorecard
    assert again.n_run == 0 and _comparable(again.scorecard) == _comparable(sc)

    more = run_bench(_small(seeds=3), out, progress=False, plots=False)  # more seeds: only those run
    assert (more.n_run, more.n_skipped) == (8, 16)
    with pytest.raises(EvalError, match="holds a bench with other settings \\(tolerance"):
        run_bench(_small(tolerance=0.01), out, progress=False)


def test_bench_refuses_a_directory_that_is_not_a_bench(tmp_path):
    (tmp_path / "x").mkdir()
    (tmp_path / "x" / "notes.txt").write_text("mine")
    with pytest.raises(EvalError, match="does not hold a bench"):
        run_bench(_small(), tmp_path / "x", progress=False)


def test_cli_bench_list_markdown_and_readme(tmp_path, capsys):
    out = tmp_path / "b"
    args = ["bench", "--tasks", "circle", "--conditions", "default", "--policies", "zero,jmpi", "--seeds", "1"]
    assert main([*args, "--env-kwargs", json.dumps(SHORT), "--out", str(out), "--quiet", "--no-plots"]) == 0
    capsys.readouterr()
    assert main(["bench", "--markdown", str(out / "scorecard.json")]) == 0
    block = capsys.readouterr().out
    assert block == readme_markdown(load_scorecard(out / "scorecard.json"))
    assert "| zero | 0% [0-79] |" in block and "| jmpi |" in block  # one episode: Wilson [0, 0.79]

    readme = tmp_path / "README.md"
    readme.write_text("# x\n\n<!-- bench:begin b/scorecard.json -->\nstale\n<!-- bench:end -->\n\nafter\n")
    assert main(["bench", "--render-readme", str(readme)]) == 0
    text = readme.read_text()
    assert "stale" not in text and block in text and text.endswith("<!-- bench:end -->\n\nafter\n")
    assert render_readme(text, tmp_path)[0] == text  # idempotent
    assert main(["bench", "--list"]) == 0
    listed = capsys.readouterr().out
    assert "wear20" in listed and "default controllers: " + ", ".join(BC.default_policies()) in listed
    assert main(["bench", "--markdown", str(tmp_path / "none.json")]) == 2
    assert main(["bench", "--tasks", "circel", "--out", str(tmp_path / "c")]) == 2


def test_render_readme_needs_a_block(tmp_path):
    with pytest.raises(EvalError, match="no bench block"):
        render_readme("# nothing here\n", tmp_path)
    assert README_BLOCK.search("<!-- bench:begin a.json -->\nx\n<!-- bench:end -->")


def test_scorecard_markdown_prints_chaotic_policies_with_one_digit():
    row = {
        "condition": "default",
        "env": None,
        "policy": "nnbc",
        "n": 4,
        "n_failed": 0,
        "success_rate": 0.0,
        "success_rate_ci95": [0.0, 0.49],
        "success_curve": [0.0] * 31,
        "max_error_m": {"median": 0.16, "iqm": 0.1614, "iqm_ci95": [0.0312, 0.4321]},
        "steady_max_error_m": {"iqm": 0.15},
    }
    sc = {
        "protocol": {
            "version": 1,
            "tasks": ["circle"],
            "envs": ["WheeledPuma-Circle-v0"],
            "seeds": [10000],
            "tolerance": 0.006,
            "settle_time": 0.5,
            "conditions": {"default": BC.CONDITIONS["default"].to_dict()},
        },
        "notes": [],
        "provenance": None,
        "git": "abc",
        "n_episodes": 4,
        "n_expected": 4,
        "n_failed": 0,
        "rows": [{**row, "env": "WheeledPuma-Circle-v0"}],
        "pooled": [row, {**row, "policy": "jmpi"}],
    }
    md = scorecard_markdown(sc)
    assert "| nnbc | ~200 [30-400] |" in md  # one significant digit, with its interval
    assert "| jmpi | 161.40 [31.20-432.10] |" in md
    assert "~ chaotic controller" in md


# --- statistics plots ---------------------------------------------------------------------------------------


def test_success_curve_and_wear_plots_take_rows():
    from eval.output.stat_plots import plot_error_vs_wear, plot_success_curves

    rows = []
    for env in ("A", "B"):
        for pol in ("p", "q"):
            for me in (0.05, 0.2):
                rows.append(
                    {
                        "env": env,
                        "policy": pol,
                        "model_error": me,
                        "success_curve": [min(1.0, i / 20) for i in range(31)],
                        "max_error_m": {"iqm": 0.001 * (1 + me), "iqm_ci95": [0.0009, 0.0013]},
                    }
                )
    fig = plot_success_curves([r for r in rows if r["model_error"] == 0.05], mark=0.006)
    visible = [ax for ax in fig.axes if ax.get_visible()]
    assert len(visible) == 2 and all(len(ax.get_lines()) == 3 for ax in visible)  # 2 policies + the mark
    fig = plot_error_vs_wear(rows)
    ax = fig.axes[0]
    assert len(ax.get_lines()) == 2 and list(ax.get_lines()[0].get_xdata()) == [0.05, 0.2]
    with pytest.raises(ValueError, match="31 points for 5 tolerances"):
        plot_success_curves(rows, tolerances=[1e-3] * 5)


def test_policy_lists_keep_specs_with_several_keys():
    from eval.cli.bench import policy_list

    assert policy_list("nnbc:gamma=20,mu=20,jmpi, oracle:gamma=10") == [
        "nnbc:gamma=20,mu=20",
        "jmpi",
        "oracle:gamma=10",
    ]
    assert policy_list("zero,random") == ["zero", "random"]


def test_robots_all_and_the_portability_rows():
    """`--robots all` is every robot of the protocol; a bench of several robots gets one `by_robot` row per
    (condition, robot, controller), pooled over that robot's tasks, and its README block is the portability table."""
    from eval.bench.scorecard import build_scorecard, readme_markdown, robot_of

    assert BC.BenchConfig(robots="all").robots == tuple(BC.ROBOTS) == ("puma", "ur5", "panda", "random-arm")
    assert BC.BenchConfig(robots=("all",)).env_ids()[4] == "WheeledUR5-Circle-v0"
    assert [robot_of(f"{p}-Line-v0") for p in BC.ROBOTS.values()] == list(BC.ROBOTS)

    def ep(env, seed, err):
        return {"env": env, "policy": "zero", "seed": seed, "dynamics": "kinematic", "model_error": 0.05,
                "obs_noise": 0.0, "status": "ok", "success": err <= 0.006, "max_error_m": err}  # fmt: skip

    eps = [
        ep("WheeledPuma-Circle-v0", 0, 0.001),
        ep("WheeledPuma-Line-v0", 0, 0.003),
        ep("WheeledUR5-Circle-v0", 0, 0.5),
    ]
    protocol = {"version": 1, "robots": ["puma", "ur5"], "tasks": ["circle", "line"], "envs": [], "seeds": [0],
                "tolerance": 0.006}  # fmt: skip
    sc = build_scorecard(protocol, [], {"default": {"episodes": eps, "aggregate": []}}, n_expected=3)
    rows = {(r["robot"], r["policy"]): r for r in sc["by_robot"]}
    assert rows[("puma", "zero")]["n"] == 2 and rows[("puma", "zero")]["max_error_m"]["median"] == 0.002
    assert rows[("ur5", "zero")]["success_rate"] == 0.0
    text = readme_markdown(sc)
    assert "2 robots (puma, ur5) x 2 tasks" in text and "| puma | zero | 100% [34-100] | 2.00 |" in text
    single = build_scorecard(
        {**protocol, "robots": ["puma"]}, [], {"default": {"episodes": eps[:2], "aggregate": []}}, n_expected=2
    )
    assert "by_robot" not in single
