"""One CLI vocabulary, generated from the config dataclasses (`eval.cli.options`): every option of every
subcommand of `mobman-eval` and `mobman-train` is a field of a frozen dataclass, its help is the field's
docstring and its default the field's default (so code and --help cannot drift); the same concept has the same
option in every command; the old spellings still work for one release and say so on stderr."""

from __future__ import annotations

import argparse
import dataclasses

import pytest

from eval.cli import build_parser as eval_parser
from eval.cli import main as eval_main
from eval.cli.options import field_default, field_docs, field_of, show_default
from eval.config import EvalConfig
from train.cli import build_parser as train_parser


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


#: every command line: "mobman-eval run", ..., "mobman-train", "mobman-train report"
PARSERS: dict[str, argparse.ArgumentParser] = {
    **{f"mobman-eval {name}": p for name, p in _subparsers(eval_parser()).items()},
    "mobman-train": train_parser(),
    "mobman-train report": _subparsers(train_parser())["report"],
}


def _options(parser: argparse.ArgumentParser) -> list[argparse.Action]:
    """The options a user sees (not -h, --version, the subcommands, nor the hidden old spellings)."""
    return [
        a
        for a in parser._actions
        if a.help != argparse.SUPPRESS
        and not isinstance(a, (argparse._HelpAction, argparse._VersionAction, argparse._SubParsersAction))
    ]


def _parse(command: str, argv: list[str]) -> argparse.Namespace:
    prog, _, sub = command.partition(" ")
    parser = eval_parser() if prog == "mobman-eval" else train_parser()
    return parser.parse_args(([sub] if sub else []) + argv)


def test_every_command_is_covered():
    assert set(PARSERS) == {
        "mobman-eval run",
        "mobman-eval sweep",
        "mobman-eval bench",
        "mobman-eval paper",
        "mobman-eval speed",
        "mobman-eval picture",
        "mobman-eval readme",
        "mobman-eval timings",
        "mobman-eval compact",
        "mobman-eval plots",
        "mobman-train",
        "mobman-train report",
    }


@pytest.mark.parametrize("command", sorted(PARSERS))
def test_every_option_is_a_field_with_its_docstring_and_default(command):
    parser = PARSERS[command]
    seen = set()
    for action in _options(parser):
        field = field_of(action)
        assert field is not None, f"{command} {action.option_strings}: an option written by hand, not from a field"
        cls, name = field
        assert field not in seen, f"{cls.__name__}.{name} has two options"
        seen.add(field)
        shown = action.help.replace("%%", "%")
        assert shown.startswith(field_docs(cls)[name]), f"{command} {action.option_strings}: help is not the docstring"
        f = next(f for f in dataclasses.fields(cls) if f.name == name)
        has_default = f.default is not dataclasses.MISSING or f.default_factory is not dataclasses.MISSING
        text = show_default(field_default(cls, name)) if has_default and action.nargs != 0 else None
        if text is None:
            assert "(default:" not in shown, f"{command} {action.option_strings}: a default the field does not have"
        else:
            assert f"(default: {text})" in shown, f"{command} {action.option_strings}: default differs from the field"
        # not given: absent from the namespace, so the dataclass's own default is what runs
        assert action.default is argparse.SUPPRESS


@pytest.mark.parametrize("command", sorted(PARSERS))
def test_the_help_prints(command, capsys):
    with pytest.raises(SystemExit) as exc:
        PARSERS[command].parse_args(["--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    for old in ("--episodes N", "--policies", "--seed-start", "--controllers", "--no-progress", "--batch N"):
        if command == "mobman-eval speed" and old == "--episodes N":
            continue  # speed's --episodes: the episodes of its timed eval.run rows
        assert old not in out, f"{command} --help shows the old spelling {old}"


def test_no_options_give_the_configs_defaults():
    from eval.cli import bench, paper, run, speed
    from eval.cli.options import build
    from eval.paper import PaperConfig
    from eval.speed import SpeedConfig

    assert build(EvalConfig, _parse("mobman-eval run", []), run.EPISODES + run.OUTPUT) == EvalConfig()
    assert build(PaperConfig, _parse("mobman-eval paper", []), paper.OPTIONS) == PaperConfig()
    assert build(SpeedConfig, _parse("mobman-eval speed", []), speed.OPTIONS) == SpeedConfig()
    from eval.bench.config import BenchConfig

    assert build(BenchConfig, _parse("mobman-eval bench", []), bench.PROTOCOL) == BenchConfig()
    from eval.cli import picture
    from eval.output.picture import PictureConfig

    assert build(PictureConfig, _parse("mobman-eval picture", []), picture.OPTIONS) == PictureConfig()


def test_mobman_train_with_no_options_trains_the_default_config():
    from train.cli import config_from_args
    from train.config import TrainConfig

    assert config_from_args(_parse("mobman-train", [])) == TrainConfig(progress_bar=False)  # stderr: no terminal


#: concept -> option, and the commands that take it (DESIGN.md "Release 0.3", "CLI vocabulary")
VOCABULARY = {
    "--policy": ("run", "bench", "speed", "picture", "train report"),
    "--env": ("run", "picture", "train"),
    "--dynamics": ("run", "paper", "picture", "train"),
    "--seed": ("run", "bench", "picture", "train", "train report"),
    "--seeds": ("run", "bench", "paper", "train report"),
    "--out": ("run", "sweep", "bench", "paper", "speed", "picture", "train", "train report"),
    "--workers": ("run", "sweep", "bench", "paper", "train report"),
    "--batch-size": ("run", "sweep", "bench", "paper", "speed"),
    "--env-kwargs": ("run", "bench", "train", "train report"),
    "--quiet": ("run", "sweep", "bench", "paper", "speed", "train"),
    "--no-plots": ("run", "sweep", "bench", "train report"),
    "--overwrite": ("run", "paper", "speed", "train"),
    "--tolerance": ("run", "bench", "train report"),
}


@pytest.mark.parametrize("option", sorted(VOCABULARY))
def test_one_name_per_concept(option):
    for short in VOCABULARY[option]:
        command = ("mobman-" + short) if short.startswith("train") else f"mobman-eval {short}"
        options = {s for a in _options(PARSERS[command]) for s in a.option_strings}
        assert option in options, f"{command} has no {option}"


@pytest.mark.parametrize(
    "command, option",
    [("mobman-eval run", "--policy"), ("mobman-eval bench", "--policy"), ("mobman-eval speed", "--policy")]
    + [("mobman-train report", "--policy")],
)
def test_policy_is_repeatable_and_takes_comma_lists(command, option):
    args = _parse(command, [option, "nnbc:gamma=20,mu=20,jmpi", option, "zero"])
    field = next(field_of(a)[1] for a in _options(PARSERS[command]) if option in a.option_strings)
    assert getattr(args, field) == ["nnbc:gamma=20,mu=20", "jmpi", "zero"]


def test_dynamics_and_env_are_repeatable_comma_lists():
    args = _parse("mobman-eval run", ["--dynamics", "kinematic,physics", "--env", "A-v0", "--env", "B-v0,C-v0"])
    assert args.dynamics == ["kinematic", "physics"] and args.envs == ["A-v0", "B-v0", "C-v0"]
    assert _parse("mobman-eval paper", ["--dynamics", "physics"]).dynamics == ["physics"]


#: (command, old spelling, new spelling, what the deprecation message says)
OLD_SPELLINGS = [
    ("mobman-eval run", ["--episodes", "3"], ["--seeds", "3"], "--episodes is now --seeds"),
    ("mobman-eval bench", ["--policies", "zero,jmpi"], ["--policy", "zero,jmpi"], "--policies is now --policy"),
    ("mobman-eval bench", ["--seed-start", "7"], ["--seed", "7"], "--seed-start is now --seed"),
    ("mobman-eval speed", ["--batch", "2"], ["--batch-size", "2"], "--batch is now --batch-size"),
    (
        "mobman-eval paper",
        ["--dynamics", "both"],
        ["--dynamics", "kinematic,physics"],
        "--dynamics both is now --dynamics kinematic,physics",
    ),
    ("mobman-train", ["--no-progress"], ["--quiet"], "--no-progress is now --quiet"),
    ("mobman-train report", ["--episodes", "4"], ["--seeds", "4"], "--episodes is now --seeds"),
    ("mobman-train report", ["--controllers", "zero,jmpi"], ["--policy", "zero,jmpi"], "--controllers is now --policy"),
]


@pytest.mark.parametrize("command, old, new, message", OLD_SPELLINGS)
def test_old_spellings_work_for_one_release_and_say_so(command, old, new, message, capsys):
    assert vars(_parse(command, new)) == vars(_parse(command, old))
    err = capsys.readouterr().err
    assert err.count("DeprecationWarning") == 1 and message in err and "next release" in err, err
    _parse(command, new)
    assert capsys.readouterr().err == ""


def test_an_old_spelling_runs_to_the_same_checks(tmp_path, capsys):
    out = tmp_path / "o"
    assert eval_main(["run", "--policy", "zero", "--episodes", "0", "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "--episodes is now --seeds" in err and "episodes must be an integer >= 1" in err and "--seeds 5" in err
    assert "Traceback" not in err and not out.exists()


@pytest.mark.parametrize(
    "argv, needle",
    [
        (
            ["run", "--dynamics", "kinematic,warp"],
            "unknown dynamics 'warp' in 'kinematic,warp'; accepted: physics, kinematic",
        ),
        (["run", "--env-kwargs", "[1]"], "--env-kwargs must be a JSON object such as"),
        (["run", "--seeds", "x"], "argument --seeds: invalid int value: 'x'"),
        (["bench", "--track", "nope"], "invalid choice: 'nope'"),
        (["paper", "--dynamics", "warp"], "unknown dynamics 'warp'"),
    ],
)
def test_bad_values_exit_2_with_the_accepted_ones(argv, needle, capsys):
    with pytest.raises(SystemExit) as exc:
        eval_main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert needle in err and "Traceback" not in err, err


def test_mobman_train_help_lists_report(capsys):
    with pytest.raises(SystemExit):
        train_parser().parse_args(["--help"])
    out = capsys.readouterr().out
    assert "commands:" in out and "report" in out.split("commands:")[1]


def test_report_options_come_after_report(capsys):
    from train.cli import main

    with pytest.raises(SystemExit) as exc:
        main(["--algo", "ppo", "report", "runs/x"])
    assert exc.value.code == 2
    assert "report takes no training options" in capsys.readouterr().err


def test_resume_names_the_options_it_refuses(tmp_path, capsys):
    pytest.importorskip("stable_baselines3")
    from train.cli import main

    assert main(["--resume", str(tmp_path), "--env", "WheeledPuma-Line-v0", "--quiet", "--timesteps", "5"]) == 2
    err = capsys.readouterr().err
    assert "only --timesteps and --quiet may be given with it, not --env" in err


def test_defaults_of_dynamics_and_their_reasons_are_in_the_help():
    """`run` (and every evaluation) defaults to physics, `mobman-train` to kinematic: on purpose, and each help
    says which and why (the fields' docstrings)."""
    from train.config import TrainConfig

    run_help = next(a.help for a in _options(PARSERS["mobman-eval run"]) if "--dynamics" in a.option_strings)
    train_help = next(a.help for a in _options(PARSERS["mobman-train"]) if "--dynamics" in a.option_strings)
    assert EvalConfig().dynamics == ("physics",) and field_default(TrainConfig, "dynamics") == "kinematic"
    assert "(default: physics)" in run_help and "30 kinematic ones" in run_help
    assert "(default: kinematic)" in train_help and "30 kinematic ones" in train_help


def test_the_run_table_of_eval_readme_has_every_option_of_run():
    """eval/README.md's table of `mobman-eval run` options names each option of the parser, and no other."""
    import re
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / "eval" / "README.md").read_text()
    table = text.split("<!-- --8<-- [start:run] -->\n")[1].split("\n\n")[0]
    documented = set()
    for line in table.splitlines()[2:]:
        documented |= set(re.findall(r"`(--[a-z-]+)", re.split(r"(?<!\\)\|", line)[1]))
    options = {s for a in _options(PARSERS["mobman-eval run"]) for s in a.option_strings}
    assert documented == options, f"missing from the table: {options - documented}; not options: {documented - options}"
