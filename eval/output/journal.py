"""The journal `episodes.jsonl` of a sweep (and of a run): one complete episode record per line, appended with one
`write` as each episode ends; a torn last line (the process was killed mid-write) is dropped on load."""

from __future__ import annotations

import contextlib
import json
import os
import stat
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

from eval.errors import EvalError
from eval.output.files import write_error

JOURNAL = "episodes.jsonl"
#: Cap on a journal read back (a record is about 2 kB: a million episodes).
MAX_JOURNAL_BYTES = 4 * 2**30


def episode_key(rec: Any) -> tuple:
    """(env, policy, seed, condition, dynamics, model_error, obs_noise) of a record (a dict) or a task (attributes
    of those names, `eval.execution.tasks.Task`): what identifies an episode in a grid (a record written before
    records named their condition has None there, so its episode runs again)."""
    get: Callable[[str], Any] = rec.get if isinstance(rec, dict) else lambda k: getattr(rec, k)
    return (
        get("env"),
        get("policy"),
        int(get("seed")),
        get("condition") or None,
        get("dynamics"),
        float(get("model_error")),
        float(get("obs_noise")),
    )


def run_key(rec: Any) -> tuple:
    """(env, policy, seed, dynamics) of a record or a task: what identifies an episode within one `run`, whose
    model_error and obs_noise are the config's for every episode (None in a task: the env's default, which its
    record resolves to a number, so `episode_key` of a run's task and of its record differ)."""
    get: Callable[[str], Any] = rec.get if isinstance(rec, dict) else lambda k: getattr(rec, k)
    return (get("env"), get("policy"), int(get("seed")), get("dynamics"))


class Journal:
    """`episodes.jsonl`: one complete JSON episode record per line; later lines win for the same episode.
    `command` ("sweep", "run", ...) names the writer in the message that refuses a second one. A write that
    fails (a full disk) raises EvalError naming the file; the lines written before it are kept."""

    def __init__(self, path: Path, command: str = "sweep"):
        self.path = Path(path)
        self.command = command
        self._fd: int | None = None

    def load(self, repair: bool = True, key: Callable[[Any], tuple] = episode_key) -> tuple[dict[tuple, dict], int]:
        """({key: record}, number of lines dropped), keyed by `key` (`episode_key`; a run's: `run_key`). A torn last line (the process was killed while writing
        it) is cut off the file (with `repair`; without, it is only left out: a check before the lock is held
        changes nothing); a line that is valid JSON but not an object is skipped with a warning; any
        other unreadable line is an error naming it."""
        from policies.agents.untrusted import FileRefused, read_regular
        from policies.agents.untrusted_json import parse_json

        if not self.path.exists():
            return {}, 0
        try:  # a regular file under a cap (never a FIFO or a device); each line through the one JSON parser
            data = read_regular(self.path, MAX_JOURNAL_BYTES, "journal")
        except FileRefused as exc:
            raise EvalError(str(exc)) from None
        records: dict[tuple, dict] = {}
        dropped = 0
        end = data.rfind(b"\n") + 1  # everything after the last newline is a torn write
        for n, line in enumerate(data[:end].splitlines(), 1):
            if not line.strip():
                continue
            try:
                rec = parse_json(line, f"line {n}")
            except FileRefused as exc:
                raise EvalError(
                    f"{self.path} line {n} is not an episode record ({exc}); the file was edited or "
                    f"damaged: delete that line (its episode then runs again)"
                ) from None
            if not isinstance(rec, dict):  # valid JSON but no record (an edit, a foreign tool): skipped
                warnings.warn(
                    f"{self.path} line {n} is {type(rec).__name__}, not an episode record: skipped (its "
                    f"episode runs again)",
                    stacklevel=2,
                )
                dropped += 1
                continue
            try:
                records[key(rec)] = rec
            except (ValueError, KeyError, TypeError) as exc:
                raise EvalError(
                    f"{self.path} line {n} is not an episode record ({exc}); the file was edited or "
                    f"damaged: delete that line (its episode then runs again)"
                ) from None
        if end < len(data):
            dropped += 1
            if repair:
                os.truncate(self.path, end)
        return records, dropped

    def open(self, fresh: bool = False) -> None:
        """Open for appending, holding an exclusive lock: two sweeps cannot write one directory at once.
        `fresh`: empty the file once the lock is held (a run starts a new journal)."""
        try:  # O_NONBLOCK: a FIFO planted under the journal's name fails here instead of blocking the run
            self.path.parent.mkdir(parents=True, exist_ok=True)
            fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT | getattr(os, "O_NONBLOCK", 0), 0o644)
        except OSError as exc:
            if self.path.exists() and not self.path.is_file():
                raise EvalError(f"{self.path} is not a regular file; delete it (the journal is a plain file)") from None
            raise write_error(self.path, exc) from None
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            os.close(fd)
            raise EvalError(f"{self.path} is not a regular file; delete it (the journal is a plain file)")
        lock_exclusive(fd, self.path.parent, self.command)
        if fresh:
            os.ftruncate(fd, 0)
        self._fd = fd

    def append(self, rec: dict) -> None:
        """One record as one line, written with a single `write` call (the kernel appends it whole); a line
        cut short by a full disk is cut off again, so the file ends with whole records."""
        data = (json.dumps(rec, allow_nan=False) + "\n").encode()
        assert self._fd is not None, "Journal.open() first"
        start = os.lseek(self._fd, 0, os.SEEK_END)
        view = memoryview(data)
        try:
            while view:
                n = os.write(self._fd, view)
                view = view[n:]
        except OSError as exc:
            with contextlib.suppress(OSError):
                os.ftruncate(self._fd, start)
            raise write_error(self.path, exc, "the episodes already in it are kept") from None

    def close(self) -> None:
        if self._fd is not None:
            try:
                with contextlib.suppress(OSError):  # a full disk: the error that stopped the run is the one to say
                    os.fsync(self._fd)
            finally:
                os.close(self._fd)
                self._fd = None


def lock_exclusive(fd: int, folder: Path, command: str) -> None:
    """Hold an exclusive `flock` on `fd` (released when it is closed), or close it and raise EvalError: another
    `command` is writing to `folder`."""
    try:
        import fcntl

        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except ImportError:  # pragma: no cover - not POSIX: no lock
        pass
    except OSError:
        os.close(fd)
        raise EvalError(f"another {command} is writing to {folder}; wait for it or use another --out") from None


class FolderLock:
    """An exclusive lock on a folder itself (its directory fd), held inside the block: a bench takes it before
    it writes bench.json, so a second bench on the same --out is refused before it changes anything."""

    def __init__(self, folder: Path, command: str):
        self.folder, self.command = Path(folder), command
        self._fd: int | None = None

    def __enter__(self) -> FolderLock:
        self._fd = os.open(self.folder, os.O_RDONLY)
        lock_exclusive(self._fd, self.folder, self.command)
        return self

    def __exit__(self, *exc: Any) -> None:
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None
