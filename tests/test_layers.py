"""The import graph: no cycle anywhere (imports inside functions count) and every import points down the layers
that each package's docstring states (mobman_env <- policies <- eval <- train; eval's own layers)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("mobman_env", "policies", "eval", "train")
#: package -> the packages it may import (the dependency direction of DESIGN.md)
ALLOWED = {
    "mobman_env": set(),
    "policies": {"mobman_env"},
    "eval": {"mobman_env", "policies"},
    "train": {"mobman_env", "policies", "eval"},
}
#: eval's layers (eval/__init__.py): a module may import its own layer's siblings only as stated there, and
#: any module of a lower-numbered layer
EVAL_LAYERS = {
    "eval.errors": 1,
    "eval.metrics": 1,
    "eval.heldout": 1,
    "eval.conditions": 2,
    "eval.rollout": 2,
    "eval.schemas": 2,
    "eval.config": 3,
    "eval.execution": 4,
    "eval.checks": 5,
    "eval.output": 5,
    "eval.grid": 6,
    "eval.runner": 7,
    "eval.sweep": 7,
    "eval.paper": 8,
    "eval.bench": 8,
    "eval.speed": 9,
    "eval.timings": 9,
    "eval.redraw": 9,
    "eval.cli": 10,
    "eval.__main__": 11,
    "eval": 11,
}


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py")}


def _imports(path: Path, name: str, known: set[str]) -> set[str]:
    """Every first-party module `path` imports, anywhere in the file (functions included)."""
    tree = ast.parse(path.read_text())
    is_pkg = path.name == "__init__.py"
    found = set()
    for node in ast.walk(tree):
        targets: list[str] = []
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".")
                base = base[: len(base) - node.level + (1 if is_pkg else 0)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            targets = [mod] + [f"{mod}.{a.name}" for a in node.names]
        for t in targets:
            while t and t not in known:
                t = t.rpartition(".")[0]
            if t and t != name:
                found.add(t)
    return found


@pytest.fixture(scope="module")
def graph() -> dict[str, set[str]]:
    mods = _modules()
    return {name: _imports(path, name, set(mods)) for name, path in mods.items()}


def test_no_import_cycle(graph):
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(m: str) -> None:
        state[m] = 1
        stack.append(m)
        for d in sorted(graph.get(m, ())):
            # a module importing its own package's __init__ (implicitly, as every import does) is not a cycle
            if m.startswith(d + "."):
                continue
            if state.get(d) == 1:
                cycle = stack[stack.index(d) :] + [d]
                pytest.fail("import cycle: " + " -> ".join(cycle))
            if d not in state:
                visit(d)
        stack.pop()
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m)


def test_packages_import_downwards_only(graph):
    bad = [
        f"{m} imports {d}"
        for m, deps in graph.items()
        for d in deps
        if d.split(".")[0] != m.split(".")[0] and d.split(".")[0] not in ALLOWED[m.split(".")[0]]
    ]
    assert not bad, bad


def _layer(m: str) -> int:
    while m not in EVAL_LAYERS:
        m = m.rpartition(".")[0]
    return EVAL_LAYERS[m]


def _group(m: str) -> str:
    return ".".join(m.split(".")[:2])


def test_eval_layers(graph):
    bad = []
    for m, deps in graph.items():
        if not m.startswith("eval"):
            continue
        for d in deps:
            if not d.startswith("eval") or _group(d) == _group(m) or m.startswith(d + "."):
                continue
            if _layer(d) >= _layer(m):
                bad.append(f"{m} (layer {_layer(m)}) imports {d} (layer {_layer(d)})")
    assert not bad, bad


#: policies' sub-packages (their docstrings; policies/__init__.py): the other policies modules each may import
#: (imports inside functions count); a module may import the modules of its own sub-package
POLICIES_PARTS = {
    "policies.kernels": {"policies.base"},
    "policies.laws": {"policies.base", "policies.batched", "policies.kernels"},
    "policies.agents": {"policies.base", "policies.registry", "policies.knowledge"},
}


def test_policies_subpackages_import_what_their_docstrings_state(graph):
    """kernels <- laws: a kernel never reaches a law, a law never the registry or an agent; the agents reach the
    registry and the knowledge classes only for a residual agent's base."""
    bad = []
    for m, deps in graph.items():
        part = ".".join(m.split(".")[:2])
        if part not in POLICIES_PARTS:
            continue
        for d in deps:
            if d.split(".")[0] != "policies" or d.startswith(part + ".") or d == part:
                continue
            if not any(d == a or d.startswith(a + ".") for a in POLICIES_PARTS[part]):
                bad.append(f"{m} imports {d}")
    assert not bad, bad


def test_the_checker_sees_imports_inside_functions(tmp_path):
    p = tmp_path / "mod.py"
    p.write_text("def f():\n    from eval.cli import main\n    import policies.registry\n")
    assert _imports(p, "eval.output.x", {"eval.cli", "policies.registry", "policies"}) == {
        "eval.cli",
        "policies.registry",
    }


def test_no_product_function_is_over_80_lines():
    """Issue 35: no function or method of the four packages is over 80 lines (docstring included); a longer one
    is split at its own seams into named helpers."""
    root = ROOT
    long = []
    for pkg in ("mobman_env", "policies", "train", "eval"):
        for path in sorted((root / pkg).rglob("*.py")):
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                    lines = (node.end_lineno or node.lineno) - node.lineno + 1
                    if lines > 80:
                        long.append(f"{path.relative_to(root)}:{node.lineno} {node.name} ({lines} lines)")
    assert not long, long
