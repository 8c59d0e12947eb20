"""Whether numba will compile a module's kernels: `cold_kernels(module, ...)` names every `@njit(cache=True)`
kernel whose cache holds no machine code for this machine, this numba and this source, so that a command can
say "compiling the kernels once" before a silent minute instead of after it.

How numba decides (numba.core.caching, checked for numba 0.68): each cached function has an index file
(`<name>-<line>.pyXY.nbi`, beside the source in `__pycache__`, or in a user-wide folder where that is not
writable, or under `NUMBA_CACHE_DIR`) holding numba's version, the source file's stamp (mtime and size) and one
key per compiled signature: (signature, the target machine's magic tuple, hashes of the bytecode and closure). A
call loads machine code only when the version and the stamp match and a key with this machine's tuple and this
bytecode exists; otherwise it compiles. `cold_kernels` applies the same test to the index without loading
anything (a few small pickles; no compile, no LLVM work beyond the target's description).

Only kernels numba compiles on their own are checked: an `inline="always"` helper is compiled into its callers
and never has machine code of its own. A kernel with a fresh entry for another signature than the one a command
will use still counts as warm; the packages' `warm()` functions call every kernel with the signatures the
package passes, so after one `warm()` every checked kernel is warm (a test holds that).
"""

from __future__ import annotations

from types import ModuleType
from typing import Any


def cold_kernels(*modules: ModuleType) -> list[str]:
    """`module.name` of every cached, non-inlined numba kernel defined in `modules` that a call would compile
    (see the module docstring); empty when every one loads from numba's cache."""
    from numba.core.dispatcher import Dispatcher

    cold = []
    for module in modules:
        for name, obj in vars(module).items():
            if not isinstance(obj, Dispatcher) or obj.__module__ != module.__name__:
                continue
            inlined = obj.targetoptions.get("inline", "never") != "never"
            if inlined or not hasattr(getattr(obj, "_cache", None), "_cache_file"):
                continue  # inlined into its callers, or not cached at all: nothing of its own to load
            if not _cached(obj):
                cold.append(f"{module.__name__}.{name}")
    return cold


def _cached(kernel: Any) -> bool:
    """Whether `kernel`'s cache index (fresh for its source file and this numba) has an entry for this machine
    and this bytecode; numba's own `Cache._index_key` computes the key, so the test is numba's."""
    cache = kernel._cache
    try:
        index = cache._cache_file._load_index()
    except Exception:  # an unreadable or foreign index: numba would compile (and overwrite it)
        return False
    here = cache._index_key(None, kernel.targetctx.codegen())[1:]
    return any(key[1:] == here for key in index)
