"""`mobman-eval plots DIR` (`eval.redraw`): every committed plot is drawn again from the committed results beside
it, running no episode (the same files, each the same image), and what cannot be read is refused naming it."""

from __future__ import annotations

import io
import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from eval.cli import main
from eval.errors import EvalError
from eval.output.compact import stored_bytes
from eval.output.results import load_arrays
from eval.redraw import redraw

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "results"
#: every committed folder whose plots `mobman-eval plots` draws (a training report's: tests/test_train_report.py)
FOLDERS = sorted(
    p.parent.relative_to(RESULTS).as_posix()
    for p in [*RESULTS.rglob("scorecard.json"), *RESULTS.rglob("scorecard.json.xz"), *RESULTS.rglob("episodes.npz")]
    if list(p.parent.rglob("*.png"))
)


def _pngs(folder: Path) -> list[str]:
    return sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*.png"))


def test_the_folders_are_every_committed_folder_with_plots_but_the_training_reports():
    with_plots = {p.parent.relative_to(RESULTS).parts[0] for p in RESULTS.rglob("*.png")}
    assert {f.split("/")[0] for f in FOLDERS} == with_plots - {"rl-v2"}
    assert {"bench-v1", "bench-v3-dev", "paper", "robots-v1/kinematic"} <= set(FOLDERS)


@pytest.mark.slow
@pytest.mark.parametrize("name", FOLDERS)
def test_each_committed_plot_is_drawn_again_from_the_committed_results(name, tmp_path):
    """The folder's results files alone (its plots left behind) give back every committed plot: the same files,
    each a palette PNG of the same size, pixel for pixel the same image (up to 1% of pixels, for another
    FreeType's glyphs)."""
    src, out = RESULTS / name, tmp_path / "folder"
    shutil.copytree(src, out, ignore=shutil.ignore_patterns("*.png"))
    assert _pngs(out) == []
    assert main(["plots", str(out)]) == 0
    assert _pngs(out) == _pngs(src)
    for rel in _pngs(src):
        with Image.open(src / rel) as committed, Image.open(out / rel) as drawn:
            assert drawn.mode == committed.mode == "P" and drawn.size == committed.size, rel
            a, b = (np.asarray(i.convert("RGB")) for i in (committed, drawn))
        assert (a != b).any(axis=2).mean() <= 0.01, rel


def test_a_folder_without_results_is_refused_naming_it(tmp_path, capsys):
    assert main(["plots", str(tmp_path)]) == 2
    assert "holds neither scorecard.json nor results.json" in capsys.readouterr().err
    with pytest.raises(EvalError, match="is not a folder"):
        redraw(tmp_path / "missing")


def test_a_protocol_v1_scorecard_of_the_wrong_shape_is_refused_naming_the_field(tmp_path):
    sc = json.loads(stored_bytes(RESULTS / "robots-v1" / "physics" / "scorecard.json"))
    sc["protocol"]["tolerance"] = "6 mm"
    (tmp_path / "scorecard.json").write_text(json.dumps(sc))
    with pytest.raises(EvalError, match=r"protocol\.tolerance"):
        redraw(tmp_path)
    assert not (tmp_path / "plots").exists()


def _npz(path: Path, **arrays) -> None:
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    path.write_bytes(buf.getvalue())


def test_the_arrays_file_is_read_as_arrays_only(tmp_path):
    _npz(tmp_path / "ok.npz", ep00000__t=np.arange(3.0), ep00000__r_a=np.zeros((3, 3)), ep00007__t=np.ones(2))
    arrays = load_arrays(tmp_path / "ok.npz")
    assert sorted(arrays) == ["ep00000", "ep00007"] and sorted(arrays["ep00000"]) == ["r_a", "t"]
    _npz(tmp_path / "pickle.npz", ep00000__t=np.array([{"a": 1}], dtype=object))
    with pytest.raises(EvalError, match="cannot read the arrays file.*(pickle|allow_pickle)"):
        load_arrays(tmp_path / "pickle.npz")
    _npz(tmp_path / "name.npz", t=np.arange(3.0))
    with pytest.raises(EvalError, match=r"entry 't' is not KEY__NAME"):
        load_arrays(tmp_path / "name.npz")
    os.mkfifo(tmp_path / "fifo.npz")
    with pytest.raises(EvalError, match="not a regular file"):
        load_arrays(tmp_path / "fifo.npz")
