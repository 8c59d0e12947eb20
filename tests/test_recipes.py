"""The docs' recipes run as written: each code block under `<!-- recipe:NAME -->` in docs/recipes.md prints
the block under `<!-- recipe:NAME:output -->` (run from the repository root, on committed results)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "recipes.md"


def _block(text: str, marker: str, lang: str) -> str:
    m = re.search(rf"<!-- {re.escape(marker)} -->\n```{lang}\n(.*?)```", text, flags=re.S)
    assert m, f"docs/recipes.md has no ```{lang} block right under <!-- {marker} -->"
    return m.group(1)


@pytest.mark.parametrize("name", ["compare-two-runs"])
def test_a_recipe_prints_what_the_page_says(name):
    pytest.importorskip("pandas")
    text = PAGE.read_text(encoding="utf-8")
    code, expected = _block(text, f"recipe:{name}", "python"), _block(text, f"recipe:{name}:output", "text")
    env = {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout == expected
