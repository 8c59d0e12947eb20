"""Files: atomic writes (temporary name in the same folder, then `os.replace`), plain-JSON conversion, the output
folder (default name, the check before any rollout) and file-name slugs.

Every file is written to a temporary name in the same directory and renamed, so a crash never leaves a
half-written file and never destroys the previous version of a file before the new one is complete.
"""

from __future__ import annotations

import contextlib
import errno
import io
import json
import math
import os
import signal
import stat
import tempfile
import threading
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np

from eval.errors import EvalError


def current_umask() -> int:
    """The process's umask, read without changing it (Linux: /proc/self/status; elsewhere set and restored)."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def atomic_write_bytes(path: Path, data: bytes, mode: int | None = None) -> None:
    """Write `data` to `path` through a temporary file in the same folder and `os.replace`; the file gets
    `mode`, by default the mode a plain `open(path, "w")` would give it (0666 minus the umask), not mkstemp's
    0600."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    except OSError as exc:
        raise write_error(path, exc) from None
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            os.fchmod(f.fileno(), 0o666 & ~current_umask() if mode is None else mode)
        os.replace(tmp, path)
    except BaseException as exc:
        if os.path.exists(tmp):
            os.unlink(tmp)
        if isinstance(exc, OSError):
            raise write_error(path, exc) from None
        raise


class WriteError(EvalError):
    """A file that could not be written: `path`, the system's `os_error` and what survived (`kept`) are kept,
    so that a caller who knows more (how its command resumes, where the finished episodes are) can say it again
    with `write_error`."""

    def __init__(self, message: str, path: Path, os_error: OSError, resume: tuple[str, ...] = (), kept: str = ""):
        super().__init__(message, resume)
        self.path, self.os_error, self.kept = Path(path), os_error, kept


def write_error(
    path: Path, exc: OSError, kept: str = "", again: str = "run again", resume: tuple[str, ...] = ()
) -> WriteError:
    """The EvalError of a file that could not be written (a full disk, a read-only folder): the path, the
    system's reason and the fix (the CLIs exit 2 with it, no traceback); `kept` says what survived; `again` is
    how the command goes on once the cause is fixed ("run again": a sweep or bench resumes by itself; a `run`
    says its `--resume` and passes it in `resume`, so the CLI prints the exact command)."""
    fix = {
        errno.ENOSPC: f"free space and {again}",
        errno.EDQUOT: f"free space (your disk quota is full) and {again}",
        errno.EFBIG: f"raise the file-size limit (ulimit -f) or free space and {again}",
    }.get(exc.errno or 0, f"fix that and {again}")
    message = f"cannot write {path} ({exc.strerror or exc}); {fix}" + (f" ({kept})" if kept else "")
    return WriteError(message, path, exc, resume, kept)


def atomic_write_text(path: Path, text: str) -> None:
    atomic_write_bytes(path, text.encode("utf-8"))


def atomic_rewrite_text(path: Path, text: str) -> None:
    """Replace the text of the existing file `path` atomically as an edit in place would: a symlink stays a
    symlink (its target is rewritten) and the file keeps its mode."""
    target = Path(path).resolve()
    atomic_write_bytes(target, text.encode("utf-8"), mode=stat.S_IMODE(target.stat().st_mode))


def json_text(data: Any) -> str:
    """The text of a JSON file written by eval: plain data (`to_jsonable`), indented, NaN/inf as null."""
    return json.dumps(to_jsonable(data), indent=2, allow_nan=False) + "\n"


def atomic_write_json(path: Path, data: Any) -> None:
    atomic_write_text(path, json_text(data))


#: Colours of a saved figure's palette (`png_bytes`): the most a palette PNG holds.
PNG_COLOURS = 256


def png_bytes(fig, dpi: int = 110) -> bytes:
    """The PNG of `fig` at `dpi` as an indexed-colour image: matplotlib's render quantised to a palette of
    `PNG_COLOURS` colours (Pillow's maximum-coverage quantiser, no dithering), written with `optimize=True`.

    Measured on the 109 committed plots of docs/results (lines, markers, text and the bands' translucent fills on
    white): 13.23 MB as matplotlib's RGBA PNGs, 3.84 MB so (Pillow's fast-octree quantiser: 3.88 MB, but pixels
    moved by up to 59 of 255 in a channel and line colours turned; 64 colours: 3.77 MB, the grey grid and the bands
    tinted); every pixel stays within 19 of 255 per channel of the render, white stays white, the text is drawn as
    before. A figure with transparent pixels keeps matplotlib's RGBA (quantising would drop the transparency)."""
    from PIL import Image

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
    buf.seek(0)
    with Image.open(buf) as img:
        rgba = img.convert("RGBA")
    if rgba.getchannel("A").getextrema() != (255, 255):
        return buf.getvalue()
    indexed = rgba.convert("RGB").quantize(PNG_COLOURS, method=Image.Quantize.MAXCOVERAGE, dither=Image.Dither.NONE)
    out = io.BytesIO()
    indexed.save(out, format="PNG", optimize=True)
    return out.getvalue()


def atomic_save_figure(fig, path: Path, dpi: int = 110) -> None:
    """Write `fig` to `path` as a palette PNG (`png_bytes`), atomically."""
    atomic_write_bytes(path, png_bytes(fig, dpi))


def atomic_savez(path: Path, arrays: dict[str, np.ndarray]) -> None:
    buf = io.BytesIO()
    # the names become the archive's entries; `allow_pickle` would be taken as savez's own keyword (never a key here)
    entries: dict[str, Any] = dict(arrays)
    np.savez_compressed(buf, **entries)
    atomic_write_bytes(path, buf.getvalue())


def to_jsonable(x: Any) -> Any:
    """Plain JSON data: numpy scalars/arrays to Python, NaN/inf to None, tuples to lists."""
    if isinstance(x, dict):
        return {str(k): to_jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [to_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return to_jsonable(x.tolist())
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, (int, np.integer)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        x = float(x)
        return x if math.isfinite(x) else None
    if x is None or isinstance(x, str):
        return x
    if isinstance(x, Path):
        return str(x)
    return repr(x)


def slug(text: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "-" for c in text)


#: The signals that stop a run as Ctrl-C does: SIGINT, and SIGTERM (`timeout`, Slurm, `docker stop`).
INTERRUPTS = (signal.SIGINT, signal.SIGTERM)


def _raise_interrupt(signum: int, frame: Any) -> None:
    raise KeyboardInterrupt


class sigterm_interrupts:
    """Inside the block SIGTERM raises KeyboardInterrupt in the main thread, as Ctrl-C does, so that a run,
    sweep or bench stopped by `timeout`, Slurm or `docker stop` keeps (writes) what finished and stops its
    workers. Main thread only (elsewhere: no effect); the previous handler is restored at the end."""

    def __enter__(self) -> None:
        self._main = threading.current_thread() is threading.main_thread()
        if self._main:
            self._previous = signal.signal(signal.SIGTERM, _raise_interrupt)

    def __exit__(self, *exc: Any) -> None:
        if self._main:
            signal.signal(signal.SIGTERM, self._previous)


class interrupts_deferred:
    """Ignore Ctrl-C and SIGTERM while the block runs (a report being written is finished, not cut short); one
    that came meanwhile is raised as KeyboardInterrupt at the end (with `reraise`). Main thread only
    (elsewhere: no effect)."""

    def __init__(self, reraise: bool = True) -> None:
        self.reraise = reraise

    def __enter__(self) -> None:
        self._main = threading.current_thread() is threading.main_thread()
        self._got: list[int] = []
        if self._main:
            self._previous = {s: signal.signal(s, lambda signum, frame: self._got.append(signum)) for s in INTERRUPTS}

    def __exit__(self, *exc: Any) -> None:
        if self._main:
            for s, handler in self._previous.items():
                signal.signal(s, handler)
            if self._got and self.reraise and exc[0] is None:
                raise KeyboardInterrupt


def check_out(out: Path, overwrite: bool, flag: str = "--out") -> None:
    """Refuse an output folder before any work: a file, a non-empty folder without `overwrite`, or one this
    process cannot write to (probed by creating and removing a file; folders created for the probe are removed
    again, so a refused run leaves nothing behind)."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise EvalError(f"{flag} {str(out)!r} exists and is not a directory; choose another {flag}")
    if out.is_dir() and any(out.iterdir()) and not overwrite:
        raise EvalError(
            f"{flag} {str(out)!r} exists and is not empty; choose another {flag} or pass --overwrite "
            f"(the files of an earlier run are then replaced, others are kept)"
        )
    created: list[Path] = []
    try:
        for folder in reversed([out, *out.parents]):
            if not folder.exists():
                folder.mkdir()
                created.append(folder)
        fd, probe = tempfile.mkstemp(prefix=".mobman-write-probe-", dir=out)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise EvalError(
            f"{flag} {str(out)!r} is not writable ({exc.strerror or exc}); choose a folder you can write to"
        ) from None
    finally:
        for folder in reversed(created):
            with contextlib.suppress(OSError):
                folder.rmdir()


#: Cap on a folder's record (a sweep's config.json, a bench's bench.json: a few kB).
MAX_RECORD_BYTES = 16 * 2**20


def read_folder_record(out: Path, name: str, command: str) -> dict:
    """The record `out/name` (a sweep's config.json, a bench's bench.json) of an existing, non-empty output
    folder of `command`; EvalError telling a missing file, an unreadable one (named with its error: restore
    it, or delete the folder to start over) and one of another command apart."""
    from policies.agents.untrusted_json import read_json

    path = Path(out) / name
    if not path.exists():
        raise EvalError(f"--out {str(out)!r} exists and does not hold a {command} (no {name}); choose another --out")
    try:  # the one JSON reader: a regular file under a cap, UTF-8, bounded nesting
        record = read_json(path, MAX_RECORD_BYTES, f"{command} record")
    except (OSError, ValueError) as exc:
        raise EvalError(
            f"{path} is not readable ({exc}); restore it from a backup, or delete {str(out)!r} to start over, or "
            f"choose another --out"
        ) from None
    if not isinstance(record, dict) or record.get("command") != command:
        raise EvalError(
            f"--out {str(out)!r} exists and does not hold a {command} ({name} is not a {command}'s); choose "
            f"another --out"
        )
    return record


def resolve_out(out: str | Path | None, command: str) -> Path:
    """`out` as a Path, or the default `runs/<command>-<UTC date-time with microseconds>` (made unique when
    it is created: `make_out(..., exclusive=True)`)."""
    if out:
        return Path(out)
    stamp = datetime.now(timezone.utc).strftime("%Y%m%d-%H%M%S-%f")
    return Path("runs") / f"{command}-{stamp}"


def make_out(out: Path, exclusive: bool) -> Path:
    """Create the output folder and return it. `exclusive` (a default name): never share a folder with another
    run started at the same time; if the name is taken, `-2`, `-3`, ... is appended."""
    out = Path(out)
    if not exclusive:
        out.mkdir(parents=True, exist_ok=True)
        return out
    out.parent.mkdir(parents=True, exist_ok=True)
    for n in range(1, 1000):
        candidate = out if n == 1 else out.with_name(f"{out.name}-{n}")
        try:
            candidate.mkdir()
            return candidate
        except FileExistsError:
            continue
    raise EvalError(f"cannot create a new output folder beside {str(out)!r}: 999 names taken; pass --out")


def remove_stale(out: Path, patterns: tuple[str, ...], keep: set[Path]) -> list[Path]:
    """Delete the files under `out` matching `patterns` (glob, relative to `out`: the files a command writes)
    that are not in `keep` (what this run wrote): an --overwrite run leaves no file of an earlier run beside its
    own. Files of other names are never touched."""
    keep = {Path(p).resolve() for p in keep}
    removed = []
    for pattern in patterns:
        for path in Path(out).glob(pattern):
            if path.is_file() and path.resolve() not in keep:
                path.unlink()
                removed.append(path)
    return removed
