"""`mobman-eval picture` (`eval.output.picture`): one episode's last frame as a PNG of the asked size, with a JSON
record beside it whose command renders the same picture again; a bad `--out` or size stops before any rollout
with a message naming the fix."""

from __future__ import annotations

import json
import shlex

import pytest
from PIL import Image

from eval.cli import build_parser, main
from eval.cli import picture as picture_cli
from eval.cli.options import build
from eval.errors import EvalError
from eval.output.picture import PictureConfig


def test_a_small_picture_and_its_record(tmp_path, capsys):
    out = tmp_path / "assets" / "robot.png"
    argv = ["picture", "--out", str(out), "--dynamics", "kinematic", "--width", "96", "--height", "64"]
    assert main(argv) == 0
    with Image.open(out) as img:
        assert img.format == "PNG" and img.size == (96, 64)
        assert len(set(img.getdata())) > 10  # a rendered scene, not a blank frame
    record = json.loads(out.with_suffix(".json").read_text())
    assert record["size"] == [96, 64] and record["policy"] == "nnbc-plus" and record["dynamics"] == "kinematic"
    assert record["success"] and record["rms_error_mm"] < 6.0
    assert {"cpu", "python", "versions", "git"} <= set(record["provenance"]), record["provenance"].keys()
    # the recorded command renders this picture again: it parses into the same config
    command = shlex.split(record["command"])
    assert command[:2] == ["mobman-eval", "picture"]
    again = build(PictureConfig, build_parser().parse_args(command[1:]), picture_cli.OPTIONS)
    assert again == PictureConfig(out=str(out), dynamics="kinematic", width=96, height=64)
    assert str(out) in capsys.readouterr().out


@pytest.mark.parametrize(
    "argv, needle",
    [
        (["--out", "robot.jpg"], "--out 'robot.jpg' must name a .png file, e.g. --out docs/assets/robot.png"),
        (["--width", "32"], "--width 32 is out of range; accepted: 64..4096 pixels"),
    ],
)
def test_bad_options_stop_before_the_episode(tmp_path, monkeypatch, capsys, argv, needle):
    monkeypatch.chdir(tmp_path)
    assert main(["picture", *argv]) == 2
    err = capsys.readouterr().err
    assert needle in err and "Traceback" not in err, err
    assert not any(tmp_path.rglob("*")), "nothing is written"


def test_the_gallery_command_writes_every_robot(tmp_path, capsys):
    """`--gallery DIR`: one PNG per robot of GALLERY, of the asked size, each a rendered scene, the random arms
    three different draws, and gallery.json whose command renders the same gallery again."""
    from eval.output.picture import GALLERY

    folder = tmp_path / "gallery"
    assert main(["picture", "--gallery", str(folder), "--width", "96", "--height", "72"]) == 0
    pixels = {}
    for stem in GALLERY:
        with Image.open(folder / f"{stem}.png") as img:
            assert img.format == "PNG" and img.size == (96, 72)
            pixels[stem] = list(img.getdata())
        assert len(set(pixels[stem])) > 10, stem  # a rendered scene, not a blank frame
    assert len({tuple(pixels[f"random-arm-{i}"]) for i in range(3)}) == 3  # three different arms
    record = json.loads((folder / "gallery.json").read_text())
    assert set(record["robots"]) == set(GALLERY) and record["size"] == [96, 72]
    from eval.output.picture import PATHS

    with Image.open(folder / "paths.png") as img:  # the tasks' paths: a drawn figure, not a blank one
        assert img.format == "PNG" and len(set(img.convert("L").getdata())) > 10
    assert set(record["paths"]) == set(PATHS)
    again = build(PictureConfig, build_parser().parse_args(shlex.split(record["command"])[1:]), picture_cli.OPTIONS)
    assert again == PictureConfig(gallery=str(folder), width=96, height=72)
    assert "gallery.json" in capsys.readouterr().out


def test_the_robots_page_shows_the_committed_gallery():
    """docs/tasks.md shows every image of the gallery, each committed, small (<= 100 KB) and of the size its
    gallery.json records."""
    import re
    from pathlib import Path

    from eval.output.picture import GALLERY

    docs = Path(__file__).resolve().parents[1] / "docs"
    shown = re.findall(r"\]\(assets/gallery/([\w-]+\.png)\)", (docs / "tasks.md").read_text())
    assert sorted(shown) == sorted([*(f"{stem}.png" for stem in GALLERY), "paths.png"])
    assert (docs / "assets" / "gallery" / "paths.png").stat().st_size <= 300_000
    shown.remove("paths.png")  # the tasks' paths: a matplotlib figure, not a rendered robot
    record = json.loads((docs / "assets" / "gallery" / "gallery.json").read_text())
    assert set(record["robots"]) == set(GALLERY)
    for name in shown:
        path = docs / "assets" / "gallery" / name
        assert path.stat().st_size <= 100_000, f"{name}: {path.stat().st_size} bytes"
        with Image.open(path) as img:
            assert list(img.size) == record["size"], name


def test_traces_plot_one_episode_per_controller_and_record_them(tmp_path):
    """`--traces PNG` (`render_traces`): one episode per controller on one env and seed, a drawn figure and a
    record whose command renders the same plot again; a controller that tracks ends far below one that does not."""
    from eval.output.picture import TRACES, render_traces

    out = tmp_path / "traces.png"
    config = PictureConfig(traces=str(out), env="WheeledPuma-Circle-v0", seed=10_000, dynamics="kinematic")
    path = {"type": "circle", "radius": 0.2, "duration": 4.0}
    record = render_traces(config, {"qp": "QP", "zero": "no motion"}, path=path)
    with Image.open(out) as img:
        assert img.format == "PNG" and len(set(img.convert("L").getdata())) > 10
    assert json.loads(out.with_suffix(".json").read_text()) == json.loads(json.dumps(record))
    eps = record["episodes"]
    assert {spec: ep["status"] for spec, ep in eps.items()} == {"qp": "ok", "zero": "ok"}
    assert eps["qp"]["max_error_mm"] < 6.0 < eps["zero"]["max_error_mm"]
    again = build(PictureConfig, build_parser().parse_args(shlex.split(record["command"])[1:]), picture_cli.OPTIONS)
    assert again == config
    assert list(TRACES)[:2] == ["nnbc", "jmpi"] and "nnbc-plus" in TRACES  # the paper's laws first, ours last


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"traces": "traces.jpg"}, r"--traces 'traces.jpg' must name a .png file"),
        ({"traces": "t.png", "gallery": "g"}, r"give --gallery or --traces, not both"),
    ],
)
def test_bad_traces_options_are_refused_naming_them(kwargs, match):
    with pytest.raises(EvalError, match=match):
        PictureConfig(**kwargs).validate()


def test_the_controllers_page_shows_the_committed_traces():
    """docs/controllers.md shows assets/traces.png, rendered by the command its record names, of every family."""
    from pathlib import Path

    from eval.output.picture import TRACES

    docs = Path(__file__).resolve().parents[1] / "docs"
    page = (docs / "controllers.md").read_text()
    record = json.loads((docs / "assets" / "traces.json").read_text())
    assert "](assets/traces.png)" in page and record["command"] in " ".join(page.split())
    assert list(record["episodes"]) == list(TRACES)
    assert all(ep["status"] == "ok" and ep["max_error_mm"] > 0 for ep in record["episodes"].values())
    assert (docs / "assets" / "traces.png").stat().st_size <= 300_000
