"""mobman-eval bench: the protocol table, config checks, a small bench end to end (files, resume, budget),
the scorecard and its README block, the statistics plots.

Benches here are 1 s kinematic circles (SHORT) on two tasks: they test the machinery, not controllers."""

from __future__ import annotations

import json
import re
import shlex

import pytest
from test_eval_helpers import SHORT

from eval.bench import config as BC
from eval.bench.run import run_bench
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
        "robots": ("puma",),
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


@pytest.mark.parametrize("track", ["dev", "all"])
def test_default_conditions_are_the_tracks_and_those_this_env_can_build(track):
    cfg, notes = BC.BenchConfig(track=track).resolved()
    env_args = BC.env_arguments("WheeledPuma-Circle-v0")
    for name in BC.DEFAULT_CONDITIONS[track]:
        can = all(k in env_args for k in BC.CONDITIONS[name].env_kwargs)
        assert (name in cfg.conditions) is can
        assert any(f"condition {name!r} left out" in n for n in notes) is not can
    assert cfg.policies == BC.default_policies()
    assert cfg.seed_list("default") == tuple(range(SEED, SEED + BC.DEFAULT_SEEDS))
    assert cfg.seed_list("physics") == tuple(range(SEED, SEED + BC.DEFAULT_PHYSICS_SEEDS))
    # release 0.4's revealed draw is the heldout track (in "all", not in "dev")
    assert {BC.CONDITIONS[c].track for c in cfg.conditions} == ({"dev"} if track == "dev" else {"dev", "heldout"})
    retired = [c for c in cfg.conditions if BC.CONDITIONS[c].retired == "v2"]  # protocol v2's held-out, now dev
    assert retired == ["fast-rich", "rate50", "lag100", "noise-heavy", "combined", "scaled-arms"] + [
        c for c in ("physics-robots", "physics-combined") if c in cfg.conditions
    ]
    assert BC.CONDITIONS["noise"].obs_noise == 0.001 and BC.CONDITIONS["noise"].extra_kwargs == {"obs_noise_vel": 0.01}
    assert BC.CONDITIONS["wear20"].model_error == 0.2 and BC.CONDITIONS["physics"].dynamics == "physics"


def test_the_heldout_track_is_the_revealed_draw_and_refused_naming_why_before_it(monkeypatch):
    """Release 0.4's seed is revealed: the held-out track is its draw (`h3-1-0.4` ...), every condition on track
    heldout. Before a release's seed is revealed the track is empty and a bench on it is refused, naming why."""
    from eval import heldout as H

    cfg, _ = BC.BenchConfig(track="heldout").resolved()
    assert cfg.conditions == tuple(f"{d['name']}-0.4" for d in H.revealed_draw("0.4"))
    assert {BC.CONDITIONS[c].track for c in cfg.conditions} == {"heldout"}
    monkeypatch.setitem(BC.DEFAULT_CONDITIONS, "heldout", ())
    with pytest.raises(EvalError, match=r"held-out track has no condition yet: release 0\.4's .*commit ae362a4"):
        BC.BenchConfig(track="heldout").resolved()


def test_a_condition_the_env_cannot_build_is_refused_by_name(monkeypatch):
    ghost = BC.Condition("ghost", "needs an env argument no env has", env_kwargs={"no_such_argument": 1.0})
    monkeypatch.setitem(BC.CONDITIONS, "ghost", ghost)
    with pytest.raises(
        EvalError, match="condition 'ghost' cannot run: this mobman_env has no env argument no_such_argument"
    ):
        _small(conditions=("default", "ghost")).resolved()


@pytest.mark.parametrize(
    "kw, match",
    [
        ({"tasks": ("circel",)}, "unknown task 'circel' \\(did you mean 'circle'\\?\\); known: circle, line"),
        ({"conditions": ("wear21",)}, "unknown condition 'wear21'.*known: default, wear20"),
        ({"robots": ("kuka",)}, "unknown robot 'kuka'; known: puma, ur5, panda, random-arm, scaled-arm"),
        ({"track": "test"}, "unknown track 'test'; accepted: dev, heldout, all"),
        ({"physics_seeds": 0}, "physics_seeds must be an integer >= 1"),
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


def test_a_condition_is_a_named_part_of_one_grid():
    cfg, _ = _small(conditions=("noise", "wear20")).resolved()
    tasks = cfg.tasks_of(("zero",))
    noise = [t for t in tasks if t.condition == "noise"]
    assert [t.env for t in noise] == ["WheeledPuma-Circle-v0"] * 2 + ["WheeledPuma-Line-v0"] * 2
    assert {(t.dynamics, t.model_error, t.obs_noise) for t in noise} == {("kinematic", 0.05, 0.001)}
    assert noise[0].env_kwargs == {**SHORT, "obs_noise_vel": 0.01} and [t.seed for t in noise[:2]] == [SEED, SEED + 1]
    assert [t.condition for t in tasks] == ["noise"] * 4 + ["wear20"] * 4 and [t.index for t in tasks] == list(range(8))
    assert {t.model_error for t in tasks if t.condition == "wear20"} == {0.2}


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
    page = (out / "scorecard.md").read_text()  # the page shows every plot written beside it, under its table
    shown = re.findall(r"!\[[^\]]*\]\((plots/[^)]+\.png)\)", page)
    assert sorted(shown) == sorted(p.relative_to(out).as_posix() for p in (out / "plots").glob("*.png"))
    assert page.index("## default") < page.index("(plots/success_default.png)") < page.index("## wear20")
    results = json.loads((out / "results.json").read_text())  # one results file, every record naming its condition
    assert results["schema"] == 4 and not (out / "conditions").exists()
    assert [r["condition"] for r in results["episodes"]] == ["default"] * 8 + ["wear20"] * 8
    assert all(isinstance(r["feasible"], bool) for r in results["episodes"])
    assert sc["schema"] == 4 and sc["protocol"]["seeds"] == [SEED, SEED + 1] and sc["protocol"]["version"] == 3
    assert sc["protocol"]["heldout_release"]["release"] == "0.4" and sc["protocol"]["heldout_release"]["revealed"]
    for row in sc["rows"]:  # protocol v3: success at 1 / 2 / 6 mm over the feasible episodes, the others counted
        block = row["feasible"]
        assert block["n_feasible"] + block["n_infeasible"] == row["n"] and block["n_unknown"] == 0
    assert sc["protocol"]["heldout_commit"] == BC.HELDOUT_COMMIT and sc["protocol"]["track"] == "dev"
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
    # schema 3: knowledge classes, the track pooled, the leaderboard entries, a sample per (condition, controller)
    assert {r["policy"]: r["knowledge"] for r in sc["rows"]} == {"zero": "none", "jmpi": "nominal"}
    assert {(r["track"], r["policy"]) for r in sc["tracks"]} == {("dev", "zero"), ("dev", "jmpi")}
    assert next(r for r in sc["tracks"] if r["policy"] == "zero")["n"] == 8
    assert [e["spec"] for e in sc["entries"]] == ["zero", "jmpi"] and sc["entries"][1]["knowledge"] == "nominal"
    assert {(x["condition"], x["policy"]) for x in sc["samples"]} == {
        (c, p) for c in ("default", "wear20") for p in ("zero", "jmpi")
    }
    assert "## The dev track" in (out / "scorecard.md").read_text()

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
    args = ["bench", "--robots", "puma", "--tasks", "circle", "--conditions", "default", "--policy", "zero,jmpi"]
    args += ["--seeds", "1"]
    assert main([*args, "--env-kwargs", json.dumps(SHORT), "--out", str(out), "--quiet", "--no-plots"]) == 0
    capsys.readouterr()
    line = json.loads((out / "bench.json").read_text())["command_line"]  # how to make this folder again
    assert line == shlex.join(
        ["mobman-eval", *args, "--env-kwargs", json.dumps(SHORT), "--out", str(out)] + ["--quiet", "--no-plots"]
    )
    assert main(["bench", "--markdown", str(out / "scorecard.json")]) == 0
    block = capsys.readouterr().out
    assert block == readme_markdown(load_scorecard(out / "scorecard.json"))
    assert "| zero | 0% [0-79] |" in block and "| jmpi |" in block  # one episode: Wilson [0, 0.79]
    # the track's table: knowledge, success at 1 / 2 / 6 mm over feasible episodes, success over all, clean
    assert "| zero | none | 0% · 0% · 0% [0-79] | 0% [0-79] | 0% [0-79] |" in block

    readme = tmp_path / "README.md"
    readme.write_text("# x\n\n<!-- bench:begin b/scorecard.json -->\nstale\n<!-- bench:end -->\n\nafter\n")
    assert main(["bench", "--render-readme", str(readme)]) == 0
    text = readme.read_text()
    assert "stale" not in text and block in text and text.endswith("<!-- bench:end -->\n\nafter\n")
    assert render_readme(text, tmp_path)[0] == text  # idempotent
    # "pooled" after the path: each track's pooled table alone (the README's dev block); another word is refused
    readme.write_text("<!-- bench:begin b/scorecard.json pooled -->\n<!-- bench:end -->\n")
    pooled = render_readme(readme.read_text(), tmp_path)[0]
    assert pooled.count("| zero |") == 1 and "| zero | none | 0% · 0% · 0% [0-79]" in pooled
    assert block.count("| zero |") > 1  # the full block also has the success per condition
    with pytest.raises(EvalError, match="'pooled' after the path"):
        render_readme("<!-- bench:begin b/scorecard.json all -->\n<!-- bench:end -->\n", tmp_path)
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
            "version": 2,
            "track": "dev",
            "heldout_commit": BC.HELDOUT_COMMIT,
            "heldout_sha256": BC.HELDOUT_SHA256,
            "robots": ["puma"],
            "tasks": ["circle"],
            "envs": ["WheeledPuma-Circle-v0"],
            "seeds": [10000],
            "seed_start": 10000,
            "kinematic_seeds": 1,
            "physics_seeds": 1,
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
        "rows": [{**row, "track": "dev", "env": "WheeledPuma-Circle-v0"}],
        "pooled": [{**row, "track": "dev"}, {**row, "track": "dev", "policy": "jmpi"}],
        "tracks": [{**row, "track": "dev"}, {**row, "track": "dev", "policy": "jmpi"}],
    }
    md = scorecard_markdown(sc)
    assert "| nnbc | unknown | 0% [0-49] | - | ~200 [30-400] |" in md  # one significant digit, with its interval
    assert "| jmpi | unknown | 0% [0-49] | - | 161.40 [31.20-432.10] |" in md
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
    from eval.cli.options import policy_list

    assert policy_list("nnbc:gamma=20,mu=20,jmpi, oracle:gamma=10") == [
        "nnbc:gamma=20,mu=20",
        "jmpi",
        "oracle:gamma=10",
    ]
    assert policy_list("zero,random") == ["zero", "random"]


def test_robots_all_and_the_per_robot_rows():
    """`--robots all` is every robot of the protocol; a condition of several robots gets one `by_robot` row per
    (robot, controller), pooled over that robot's tasks, shown in its condition table."""
    from eval.bench.scorecard import build_scorecard, condition_table, robot_of

    assert BC.BenchConfig(robots="all").robots == tuple(BC.ROBOTS)
    assert BC.BenchConfig(robots=("all",)).env_ids("default")[4] == "WheeledUR5-Circle-v0"
    assert [robot_of(f"{p}-Line-v0") for p in BC.ROBOTS.values()] == list(BC.ROBOTS)

    def ep(env, seed, err):
        return {"env": env, "policy": "zero", "condition": "default", "seed": seed, "dynamics": "kinematic",
                "model_error": 0.05, "obs_noise": 0.0, "status": "ok", "success": err <= 0.006,
                "max_error_m": err}  # fmt: skip

    eps = [
        ep("WheeledPuma-Circle-v0", 0, 0.001),
        ep("WheeledPuma-Line-v0", 0, 0.003),
        ep("WheeledUR5-Circle-v0", 0, 0.5),
    ]
    protocol = {"version": 2, "robots": ["puma", "ur5"], "tasks": ["circle", "line"], "envs": [], "seeds": [0],
                "tolerance": 0.006, "policies": ["zero"],
                "conditions": {"default": BC.CONDITIONS["default"].to_dict()}}  # fmt: skip
    sc = build_scorecard(protocol, [], {"episodes": eps}, n_expected=3)
    rows = {(r["robot"], r["policy"]): r for r in sc["by_robot"]}
    assert rows[("puma", "zero")]["n"] == 2 and rows[("puma", "zero")]["max_error_m"]["median"] == 0.002
    assert rows[("ur5", "zero")]["success_rate"] == 0.0
    table = condition_table(sc, "default")
    assert "| controller | puma | ur5 |" in table and "| zero | 100% · 2.00 | 0% · 500.00 |" in table
    single = build_scorecard(protocol, [], {"episodes": eps[:2]}, n_expected=2)
    assert single["by_robot"] == []


def test_the_held_out_track_is_the_one_committed_before_tuning():
    """The held-out conditions hash to HELDOUT_SHA256: changing one is a new protocol version, not an edit."""
    assert BC.heldout_digest() == BC.HELDOUT_SHA256
    assert BC.DEFAULT_CONDITIONS["heldout"] == tuple(n for n, c in BC.CONDITIONS.items() if c.track == "heldout")
    assert not set(BC.DEFAULT_CONDITIONS["dev"]) & set(BC.DEFAULT_CONDITIONS["heldout"])


def test_the_ladder_reads_the_fastest_rung_tracked():
    from eval.bench.scorecard import ladder

    conds = {n: BC.CONDITIONS[n].to_dict() for n in ("ladder-20s", "ladder-10s", "ladder-5s", "ladder-2.5s")}
    rates = {"a": (1.0, 0.95, 0.9, 0.2), "b": (1.0, 0.5, 0.95, 0.0), "c": (0.8, 0.0, 0.0, 0.0)}
    pooled = [
        {"condition": n, "policy": p, "success_rate": r[i], "success_rate_ci95": None, "knowledge": "none"}
        for p, r in rates.items()
        for i, n in enumerate(conds)
    ]
    got = {e["policy"]: e["fastest"] for e in ladder(pooled, {"conditions": conds, "policies": list(rates)})}
    assert got == {"a": 5.0, "b": 5.0, "c": None}  # b fails 10 s but tracks 5 s: the fastest rung tracked


# --- a refused bench changes nothing ---------------------------------------------------------------------------
BENCH_ARGS = ["bench", "--tasks", "circle", "--conditions", "default", "--seeds", "1", "--quiet", "--no-plots"]


@pytest.mark.parametrize("refusal", ["unknown policy", "another bench", "changed settings"])
def test_a_refused_bench_leaves_bench_json_as_it_was(tmp_path, capsys, refusal):
    from eval.output.journal import FolderLock

    out = tmp_path / "bench"
    args = [*BENCH_ARGS, "--env-kwargs", json.dumps(SHORT), "--out", str(out)]
    assert main([*args, "--policy", "zero"]) == 0
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    capsys.readouterr()
    if refusal == "unknown policy":
        code, match = main([*args, "--policy", "zero,nosuch"]), "unknown policy 'nosuch'"
    elif refusal == "another bench":
        with FolderLock(out, "bench"):
            code, match = main([*args, "--policy", "zero,jmpi"]), f"another bench is writing to {out}"
    else:  # the bench folder was made with other settings: refused up front
        cfg = out / "bench.json"
        cfg.write_text(cfg.read_text().replace('"tolerance": 0.006', '"tolerance": 0.01'))
        before[cfg] = cfg.read_bytes()
        code, match = main([*args, "--policy", "zero,jmpi"]), "holds a bench with other settings"
    err = capsys.readouterr().err
    assert code == 2 and match in err and "Traceback" not in err, err
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before


@pytest.mark.parametrize("command", ["bench", "sweep"])
def test_a_corrupt_record_is_named_as_corrupt_not_missing(tmp_path, capsys, command):
    import yaml

    out = tmp_path / command
    if command == "bench":
        args = [*BENCH_ARGS, "--env-kwargs", json.dumps(SHORT), "--out", str(out), "--policy", "zero"]
        record = out / "bench.json"
    else:
        spec = {"envs": ["WheeledPuma-Circle-v0"], "policies": ["zero"], "seeds": {"start": SEED, "count": 1}}
        (tmp_path / "s.yaml").write_text(yaml.safe_dump({**spec, "dynamics": ["kinematic"], "env_kwargs": SHORT}))
        args = ["sweep", "--config", str(tmp_path / "s.yaml"), "--out", str(out), "--quiet", "--no-plots"]
        record = out / "config.json"
    assert main(args) == 0
    record.write_text(record.read_text()[:-20])  # torn
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    capsys.readouterr()
    assert main(args) == 2
    err = capsys.readouterr().err
    assert (
        f"{record} is not readable ({record}: not valid JSON" in err
        and "restore it" in err
        and "no " + record.name not in err
    )
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before


def test_against_reuses_the_committed_baselines_after_a_bit_for_bit_sample(tmp_path):
    """`--against DIR`: the committed baselines' sample episodes are run again and equal bit for bit, so only the
    new controller runs and its rows join the committed ones (and its probability of improvement against the
    committed reference's episodes); a sample that differs makes the bench run the baselines too, and say why."""
    base = _small(conditions=("default",), policies=("qp", "clik"), tasks=("circle",))
    committed = run_bench(base, tmp_path / "committed", progress=False, plots=False).scorecard
    mine = run_bench(
        _small(conditions=("default",), policies=("jmpi",), tasks=("circle",)),
        tmp_path / "mine",
        progress=False,
        plots=False,
        against=tmp_path / "committed",
    )
    bench = json.loads((tmp_path / "mine" / "bench.json").read_text())
    assert bench["against"]["samples_equal"] is True and len(bench["against"]["samples"]) == 2
    assert mine.n_run == 2  # jmpi's 2 episodes only
    sc = mine.scorecard
    assert [e["spec"] for e in sc["entries"]] == ["qp", "clik", "jmpi"]
    kept = [r for r in sc["pooled"] if r["policy"] in ("qp", "clik")]
    assert kept == [r for r in committed["pooled"] if r["policy"] in ("qp", "clik")]
    assert {(r["policy"], r["reference"]) for r in sc["prob_improvement"]} >= {("jmpi", "qp"), ("clik", "qp")}

    data = json.loads((tmp_path / "committed" / "scorecard.json").read_text())
    data["samples"][0]["fields"]["max_error_m"] += 1e-12  # a machine that does not reproduce it
    (tmp_path / "committed" / "scorecard.json").write_text(json.dumps(data))
    again = run_bench(
        _small(conditions=("default",), policies=("jmpi",), tasks=("circle",)),
        tmp_path / "again",
        progress=False,
        plots=False,
        against=tmp_path / "committed",
    )
    bench = json.loads((tmp_path / "again" / "bench.json").read_text())
    assert bench["against"]["samples_equal"] is False and any(
        "differs in max_error_m" in x for x in bench["against"]["samples"]
    )
    assert again.n_run == 6 and any("baselines were run again" in n for n in again.scorecard["notes"])


def test_against_alone_runs_the_committed_protocol(tmp_path, capsys):
    """`mobman-eval bench --against DIR --policy X`: the seeds, first seed, tolerance, settle time and env
    arguments the command line leaves out are the committed scorecard's, so the bench is comparable as written
    (before, the defaults of 5 / 2 seeds were refused against a committed bench of 10 / 5); one given that
    differs is still refused, naming it."""
    run_bench(
        _small(conditions=("default",), policies=("zero",), tasks=("circle",), seeds=3),
        tmp_path / "c",
        progress=False,
        plots=False,
    )
    args = ["bench", "--robots", "puma", "--tasks", "circle", "--conditions", "default", "--quiet", "--no-plots"]
    assert main([*args, "--against", str(tmp_path / "c"), "--policy", "jmpi", "--out", str(tmp_path / "m")]) == 0
    bench = json.loads((tmp_path / "m" / "bench.json").read_text())
    assert bench["kinematic_seeds"] == 3 and bench["env_kwargs"] == SHORT and bench["against"]["samples_equal"]
    capsys.readouterr()
    assert (
        main(
            [*args, "--against", str(tmp_path / "c"), "--policy", "jmpi", "--seeds", "2", "--out", str(tmp_path / "n")]
        )
        == 2
    )
    assert "kinematic_seeds: 3 there, 2 here" in capsys.readouterr().err


def test_against_refuses_another_protocol(tmp_path):
    run_bench(
        _small(conditions=("default",), policies=("zero",), tasks=("circle",)),
        tmp_path / "c",
        progress=False,
        plots=False,
    )
    with pytest.raises(EvalError, match="not the committed scorecard's protocol.*kinematic_seeds: 2 there, 3 here"):
        run_bench(
            _small(conditions=("default",), policies=("jmpi",), tasks=("circle",), seeds=3),
            tmp_path / "m",
            progress=False,
            against=tmp_path / "c",
        )
    with pytest.raises(EvalError, match="name them with --policy"):
        run_bench(BC.BenchConfig(), tmp_path / "n", progress=False, against=tmp_path / "c")


def test_v3_success_is_over_feasible_episodes_and_counts_the_others():
    from eval.metrics import feasible_success

    def ep(err, feasible, status="ok"):
        return {"max_error_m": err, "feasible": feasible, "status": status}

    eps = [ep(0.0005, True), ep(0.0015, True), ep(0.004, True), ep(0.05, True), ep(0.0001, False), ep(0.0, None)]
    eps.append(ep(None, True, status="failed"))  # a failed feasible episode is a failure, never left out
    block = feasible_success(eps)
    assert block["tolerances_m"] == [0.001, 0.002, 0.006]
    assert (block["n_feasible"], block["n_infeasible"], block["n_unknown"]) == (5, 1, 1)
    assert block["success"] == [0.2, 0.4, 0.6]  # the infeasible 0.1 mm episode and the unknown one do not count
    assert block["success_ci95"][2] == pytest.approx([0.2307, 0.8824], abs=1e-4)  # Wilson, 3 of 5
    none = feasible_success([ep(0.001, False)])
    assert none["success"] == [None] * 3 and none["n_infeasible"] == 1


@pytest.mark.parametrize(
    "subset",
    [{"conditions": ("wear20",)}, {"conditions": ("wear20",), "tasks": ("circle",)}, {"tasks": ("line",)}],
)
def test_against_a_subset_of_the_committed_cells_compares_the_cells_it_ran(tmp_path, subset):
    """`--against DIR --conditions X` (0.3: a KeyError after every episode ran) and any subset of robots and tasks:
    the baselines' rows are the committed cells this bench ran; their rows pooled over cells that did not run are
    left out, and a note says so."""
    base = _small(policies=("qp", "zero"))
    run_bench(base, tmp_path / "c", progress=False, plots=False)
    mine = run_bench(
        _small(policies=("jmpi",), **subset), tmp_path / "m", progress=False, plots=False, against=tmp_path / "c"
    )
    sc = mine.scorecard
    ran = {(c, e) for c, d in sc["protocol"]["conditions"].items() for e in d["envs"]}
    assert {(r["condition"], r["env"]) for r in sc["rows"]} == ran
    assert {r["policy"] for r in sc["rows"]} == {"qp", "zero", "jmpi"}
    assert mine.n_run == 2 * len(ran) and sc["n_episodes"] == 3 * 2 * len(ran)
    assert [t["policy"] for t in sc["tracks"]] == ["jmpi"]  # the baselines' track rows pool cells not run here
    assert {r["policy"] for r in sc["prob_improvement"]} == {"jmpi"}  # and so do their probabilities
    assert any("subset of the committed cells" in n for n in sc["notes"])
    assert (tmp_path / "m" / "scorecard.md").is_file()


def test_against_a_compacted_committed_scorecard_reads_it_and_hashes_its_json(tmp_path):
    """A committed bench whose scorecard is stored compacted (scorecard.json.xz, as docs/results keeps them) is a
    valid --against DIR, and the hash recorded for it is that of its JSON bytes: the same as before compaction."""
    import hashlib

    from eval.bench.against import load_against
    from eval.output.compact import compact

    run_bench(
        _small(conditions=("default",), policies=("zero",), tasks=("circle",), seeds=2),
        tmp_path / "c",
        progress=False,
        plots=False,
    )
    plain = hashlib.sha256((tmp_path / "c" / "scorecard.json").read_bytes()).hexdigest()
    compact(tmp_path / "c" / "scorecard.json")
    assert load_against(tmp_path / "c")[1] == plain
    args = ["bench", "--robots", "puma", "--tasks", "circle", "--conditions", "default", "--quiet", "--no-plots"]
    assert main([*args, "--against", str(tmp_path / "c"), "--policy", "jmpi", "--out", str(tmp_path / "m")]) == 0
    assert json.loads((tmp_path / "m" / "bench.json").read_text())["against"]["samples_equal"]
