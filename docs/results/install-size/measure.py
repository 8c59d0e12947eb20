"""What mobman and each of its extras cost on disk, measured from the installed distributions' own file lists
(writes `install-size.md` and `install-size.json` beside this script).

For each install (the core: `pip install mobman`; then every extra of pyproject.toml) the dependency closure is
resolved against this Python's installed distributions: the requirements of pyproject.toml (a `mobman[...]`
requirement expands to those extras), then every distribution's own requirements, their environment markers
evaluated here with the extras asked for. A distribution's size is the sum of the file sizes its RECORD lists
(what the installer wrote: code, compiled libraries, data, `.pyc`), in MB of 10^6 bytes. An extra's figure is
what it adds to the core (a distribution the core needs counts there, once). A requirement not installed here
is named, never guessed. The figures are those of this machine's wheels (torch: the CPU build, as the README's
commands install it); another platform's wheels differ in size.

Usage (from the repository root, in an environment with `pip install -e ".[test]"`, which holds every extra):

    python docs/results/install-size/measure.py

`mobman-eval readme README.md docs/getting-started.md` then copies its tables into the pages (a test keeps them
equal to install-size.md).
"""

from __future__ import annotations

import importlib.metadata as md
import json
import platform
import sys
from pathlib import Path

from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

ROOT = Path(__file__).resolve().parents[3]
HERE = Path(__file__).resolve().parent
#: the installs the README's short table shows (the others are in the full table of docs/getting-started.md)
HEADLINE = ("rl", "cluster", "all", "test")


def project_requirements(pyproject: dict, extra: str | None) -> list[Requirement]:
    """The requirements of the core (`extra` None) or of one extra, a `mobman[a,b]` requirement expanded."""
    project = pyproject["project"]
    raw = project["dependencies"] if extra is None else project["optional-dependencies"][extra]
    out: list[Requirement] = []
    for text in raw:
        req = Requirement(text)
        if canonicalize_name(req.name) == canonicalize_name(project["name"]):
            for sub in sorted(req.extras):
                out += project_requirements(pyproject, sub)
        else:
            out.append(req)
    return out


def closure(reqs: list[Requirement]) -> tuple[dict[str, md.Distribution], list[str]]:
    """(installed distributions the requirements need, transitively, by canonical name; requirements not
    installed here)."""
    found: dict[str, md.Distribution] = {}
    missing: list[str] = []
    seen: set[tuple[str, str]] = set()
    todo = [(req, "") for req in reqs]
    while todo:
        req, extra = todo.pop()
        if req.marker is not None and not req.marker.evaluate({"extra": extra}):
            continue
        name = canonicalize_name(req.name)
        for wanted in ("", *sorted(req.extras)):
            if (name, wanted) in seen:
                continue
            seen.add((name, wanted))
            try:
                dist = found.get(name) or md.distribution(req.name)
            except md.PackageNotFoundError:
                missing.append(str(req))
                break
            found[name] = dist
            todo += [(Requirement(r), wanted) for r in dist.requires or ()]
    return found, sorted(set(missing))


def size_mb(dist: md.Distribution) -> float:
    """The sum of the sizes RECORD lists for `dist`, in MB (entries without a size, such as RECORD itself, count 0)."""
    return sum(f.size or 0 for f in dist.files or ()) / 1e6


def measure(pyproject: dict) -> dict:
    """Per install: the distributions it adds to the core with their sizes, and the requirements not installed."""
    core, core_missing = closure(project_requirements(pyproject, None))
    sizes = {name: size_mb(d) for name, d in core.items()}
    installs = {"core": {"adds": sorted(core), "missing": core_missing}}
    for extra in pyproject["project"]["optional-dependencies"]:
        dists, missing = closure(project_requirements(pyproject, extra))
        sizes.update({name: size_mb(d) for name, d in dists.items()})
        installs[extra] = {"adds": sorted(set(dists) - set(core)), "missing": missing}
    for entry in installs.values():
        entry["mb"] = round(sum(sizes[n] for n in entry["adds"]), 1)
    return {
        "python": platform.python_version(),
        "platform": f"{sys.platform}-{platform.machine()}",
        "installs": installs,
        "distributions_mb": {n: round(mb, 2) for n, mb in sorted(sizes.items())},
    }


def _row(name: str, entry: dict, sizes: dict[str, float], extras: dict, core_mb: float) -> str:
    label = "`pip install mobman` (the core)" if name == "core" else f"`[{name}]`"
    if name != "core":
        label += _includes(extras[name])
    largest = sorted(entry["adds"], key=lambda n: -sizes[n])[:3]
    big = ", ".join(f"{n} {sizes[n]:.0f}" for n in largest) or "-"
    missing = f" (not installed here: {', '.join(entry['missing'])})" if entry["missing"] else ""
    total = entry["mb"] + (core_mb if name != "core" else 0.0)
    return f"| {label} | {entry['mb']:.0f} MB | {total:.0f} MB | {len(entry['adds'])} | {big}{missing} |"


def _includes(raw: list[str]) -> str:
    """ " = rl, video" for an extra made only of other extras (an alias or a bundle), else ""."""
    subs = [sorted(Requirement(r).extras) for r in raw]
    if all(subs) and len(raw) == 1:
        return " = " + ", ".join(f"`[{s}]`" for s in subs[0])
    return ""


def markdown(result: dict, extras: dict) -> str:
    """install-size.md: the headline table (README) and the table of every extra (docs/getting-started.md)."""
    sizes, installs = result["distributions_mb"], result["installs"]
    head = [
        "| install | adds on disk | with the core | distributions | the largest (MB) |",
        "|---|---:|---:|---:|---|",
    ]
    core_mb = installs["core"]["mb"]
    short = [_row(n, installs[n], sizes, extras, core_mb) for n in ("core", *HEADLINE)]
    full = [_row(n, e, sizes, extras, core_mb) for n, e in installs.items()]
    where = f"Python {result['python']}, {result['platform']}"
    return (
        "# Install size\n\n"
        f"Measured by `python docs/results/install-size/measure.py` ({where}): the sum of the file sizes in each "
        "installed distribution's RECORD, over the dependency closure of each install; an extra's figure is what "
        "it adds to the core. 1 MB = 10^6 bytes.\n\n"
        "## Install size\n\n" + "\n".join(head + short) + "\n\n"
        "## Every extra\n\n" + "\n".join(head + full) + "\n"
    )


def read_pyproject(path: Path = ROOT / "pyproject.toml") -> dict:
    """pyproject.toml as a dict (tomllib; Python 3.10: the tomli it backports)."""
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        import tomli as tomllib  # type: ignore[no-redef]
    return tomllib.loads(path.read_text(encoding="utf-8"))


def main() -> None:
    pyproject = read_pyproject()
    result = measure(pyproject)
    (HERE / "install-size.json").write_text(json.dumps(result, indent=1) + "\n", encoding="utf-8")
    text = markdown(result, pyproject["project"]["optional-dependencies"])
    (HERE / "install-size.md").write_text(text, encoding="utf-8")
    print(text)


if __name__ == "__main__":
    main()
