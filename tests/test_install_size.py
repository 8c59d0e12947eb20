"""The disk cost of each install (docs/results/install-size/measure.py): every extra of pyproject.toml is measured
in the committed file, the README and the getting-started page quote it through generated blocks, and [all] does
not pull Ray (the [cluster] extra, ~200 MB a single machine does not need)."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

from packaging.requirements import Requirement

from eval.output.readme import render_generated

ROOT = Path(__file__).resolve().parents[1]
FOLDER = ROOT / "docs" / "results" / "install-size"


def _measure():
    spec = importlib.util.spec_from_file_location("install_size_measure", FOLDER / "measure.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_every_extra_is_measured_and_all_leaves_ray_to_cluster():
    pyproject = _measure().read_pyproject()
    extras = pyproject["project"]["optional-dependencies"]
    measured = json.loads((FOLDER / "install-size.json").read_text())["installs"]
    assert set(measured) == {"core", *extras}, "rerun: python docs/results/install-size/measure.py"
    assert "ray" in measured["cluster"]["adds"] and "ray" not in measured["all"]["adds"]
    assert "ray" in measured["test"]["adds"]  # Ray's tests run in CI
    assert "torch" in measured["all"]["adds"] and not any(e["missing"] for e in measured.values())


def test_the_closure_expands_the_projects_own_extras_and_follows_requirements():
    m = _measure()
    pyproject = {
        "project": {
            "name": "mobman",
            "dependencies": ["pyyaml"],
            "optional-dependencies": {"a": ["rich>=13"], "b": ["mobman[a]", "tqdm"]},
        }
    }
    assert [r.name for r in m.project_requirements(pyproject, "b")] == ["rich", "tqdm"]
    found, missing = m.closure([Requirement("rich"), Requirement("no-such-distribution-xyz")])
    assert {"rich", "markdown-it-py", "pygments"} <= set(found) and missing == ["no-such-distribution-xyz"]
    assert m.size_mb(found["rich"]) > 0


def test_the_pages_quote_the_committed_file():
    for page in (ROOT / "README.md", ROOT / "docs" / "getting-started.md"):
        text = page.read_text()
        assert "install-size/install-size.md" in text, f"{page.name} lost its install-size block"
        assert render_generated(text, page.parent)[0] == text, f"run: mobman-eval readme {page.relative_to(ROOT)}"
