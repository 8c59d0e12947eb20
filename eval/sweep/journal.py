"""The sweep's journal `episodes.jsonl`: one complete episode record per line, appended with one `write` as each
episode ends; a torn last line (the process was killed mid-write) is dropped on load."""

from __future__ import annotations

import json
import os
import warnings
from pathlib import Path

from eval.errors import EvalError
from eval.execution.tasks import Task

JOURNAL = "episodes.jsonl"


def episode_key(rec: dict | Task) -> tuple:
    """(env, policy, seed, dynamics, model_error, obs_noise) of a record or a task: what identifies an episode."""
    get = rec.get if isinstance(rec, dict) else lambda k: getattr(rec, k)
    return (
        get("env"),
        get("policy"),
        int(get("seed")),
        get("dynamics"),
        float(get("model_error")),
        float(get("obs_noise")),
    )


class Journal:
    """`episodes.jsonl`: one complete JSON episode record per line; later lines win for the same episode."""

    def __init__(self, path: Path):
        self.path = Path(path)
        self._fd: int | None = None

    def load(self) -> tuple[dict[tuple, dict], int]:
        """({key: record}, number of lines dropped). A torn last line (the process was killed while writing
        it) is cut off the file; a line that is valid JSON but not an object is skipped with a warning; any
        other unreadable line is an error naming it."""
        if not self.path.exists():
            return {}, 0
        data = self.path.read_bytes()
        records: dict[tuple, dict] = {}
        dropped = 0
        end = data.rfind(b"\n") + 1  # everything after the last newline is a torn write
        for n, line in enumerate(data[:end].splitlines(), 1):
            if not line.strip():
                continue
            try:
                rec = json.loads(line)
            except ValueError as exc:
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
                records[episode_key(rec)] = rec
            except (ValueError, KeyError, TypeError) as exc:
                raise EvalError(
                    f"{self.path} line {n} is not an episode record ({exc}); the file was edited or "
                    f"damaged: delete that line (its episode then runs again)"
                ) from None
        if end < len(data):
            dropped += 1
            os.truncate(self.path, end)
        return records, dropped

    def open(self) -> None:
        """Open for appending, holding an exclusive lock: two sweeps cannot write one directory at once."""
        self.path.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        try:
            import fcntl

            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except ImportError:  # pragma: no cover - not POSIX: no lock
            pass
        except OSError:
            os.close(fd)
            raise EvalError(
                f"another sweep is writing to {self.path.parent}; wait for it or use another --out"
            ) from None
        self._fd = fd

    def append(self, rec: dict) -> None:
        """One record as one line, written with a single `write` call (the kernel appends it whole)."""
        data = (json.dumps(rec, allow_nan=False) + "\n").encode()
        view = memoryview(data)
        while view:
            n = os.write(self._fd, view)
            view = view[n:]

    def close(self) -> None:
        if self._fd is not None:
            try:
                os.fsync(self._fd)
            finally:
                os.close(self._fd)
                self._fd = None
