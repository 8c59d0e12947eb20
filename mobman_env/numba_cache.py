"""`njit`: numba's `njit` whose on-disk cache recovers from a corrupt file (recompiles, and says so once).

Every kernel of mobman (the engine, the controllers' laws) is compiled with `@njit(cache=True)`, and numba keeps
the machine code in `__pycache__` next to the source (or under `NUMBA_CACHE_DIR`): an index `NAME.nbi` (a
pickle of the signatures) and one `NAME.N.nbc` per signature (a pickle of the object code). numba catches a
missing file but not a damaged one (a disk that filled up, a copy cut short, two versions writing at once): an
index or data file it cannot unpickle or rebuild raised a numba traceback in every later process until someone
deleted `__pycache__` by hand. Here the dispatcher's cache is a `CheckedFunctionCache`: a file that cannot be
loaded is removed, the kernel is compiled again (numba then writes a fresh file), and one line on stderr names
the file, once per file and process. The next process finds the new file and says nothing.

This is recovery, not a defence: the index and data files are pickles that numba unpickles, so whoever can
write the cache folder can run code in every process that loads it (see docs/security.md). Keep the package's
folders (or `NUMBA_CACHE_DIR`) writable only by you.

May import numba and the standard library.
"""

from __future__ import annotations

import contextlib
import os
import sys
from collections.abc import Callable
from typing import Any

import numba
from numba.core.caching import FunctionCache

__all__ = ["CheckedFunctionCache", "njit"]

#: the files this process already reported (say it once)
_REPORTED: set[str] = set()


class CheckedFunctionCache(FunctionCache):
    """numba's per-function cache, with a load that treats any failure to read the cache as a corrupt file:
    the file is removed, the load returns nothing (numba compiles and saves again) and stderr gets one line."""

    def _load_overload(self, sig: Any, target_context: Any) -> Any:
        try:
            return super()._load_overload(sig, target_context)
        except Exception as exc:
            self._drop(sig, target_context, exc)
            return None

    def _drop(self, sig: Any, target_context: Any, exc: Exception) -> None:
        """Remove the file that could not be loaded: the index if it does not unpickle, else this signature's
        data file (the index keeps its name, and numba's save writes the file again under it); only ever one of
        this kernel's own cache files (`_own_file`)."""
        files = self._cache_file
        bad = files._index_path
        try:
            name = files._load_index().get(self._index_key(sig, target_context.codegen()))
        except Exception:
            pass
        else:
            if name is not None:
                bad = os.path.join(files._cache_path, name)
        base = self._impl.filename_base
        if not _own_file(bad, files._cache_path, base):  # an index naming a file elsewhere is itself damaged
            bad = files._index_path
        removed = False
        if _own_file(bad, files._cache_path, base):
            with contextlib.suppress(OSError):
                os.remove(bad)
                removed = True
        if bad not in _REPORTED:
            _REPORTED.add(bad)
            reason = (str(exc).splitlines() or [""])[0][:200]
            func = f"{self._py_func.__qualname__} ({self._py_func.__code__.co_filename})"
            done = "it was removed" if removed else "it was left in place (remove it by hand)"
            print(
                f"mobman: numba's cache file {bad} could not be loaded ({type(exc).__name__}: {reason}); {done} "
                f"and {func} is compiled again",
                file=sys.stderr,
            )


def _own_file(path: str, folder: str, base: str) -> bool:
    """Whether `path` is one of this kernel's cache files (`base` + `.nbi`, or `base` + `.N.nbc`) directly in the
    cache `folder`: the only files `_drop` removes, whatever name a damaged index holds (never `../x`, a link
    elsewhere or another kernel's file)."""
    name = os.path.basename(path)
    inside = os.path.dirname(os.path.realpath(path)) == os.path.realpath(folder) and not os.path.islink(path)
    ours = name == f"{base}.nbi" or (name.startswith(f"{base}.") and name.endswith(".nbc"))
    return inside and ours


def _checked(dispatcher: Any) -> Any:
    """`dispatcher` with its cache a `CheckedFunctionCache` (if it caches at all: `cache=True`)."""
    if isinstance(getattr(dispatcher, "_cache", None), FunctionCache):
        dispatcher._cache = CheckedFunctionCache(dispatcher.py_func)
    return dispatcher


def njit(*args: Any, **kwargs: Any) -> Any:
    """`numba.njit` with the same arguments; with `cache=True` the cache is a `CheckedFunctionCache`. Used as
    `@njit(cache=True)`, `njit(cache=True, inline="always")(func)` or `@njit`."""
    if args and callable(args[0]):
        return _checked(numba.njit(*args, **kwargs))
    decorate = numba.njit(*args, **kwargs)

    def wrap(func: Callable[..., Any]) -> Any:
        return _checked(decorate(func))

    return wrap
