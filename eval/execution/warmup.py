"""Compile the numba kernels before the first episode, saying so, so that a first run neither sits silent for half
a minute nor charges the compile to its first episode (a progress bar started before it read
`1/280 [00:39<3:04:38, 39.71s/ep]`: an ETA made of one compile).

`warm_kernels(announce)` asks numba's cache whether a call would compile (`mobman_env.kernel_cache`, a few
milliseconds); only then it prints one line on stderr, "compiling the kernels once (about N s) ...", and calls
the engine's and the controllers' `warm()` in this process, which writes numba's cache: spawned workers then
load the machine code instead of each compiling it again. `eval.grid.run_tasks` calls it before it starts its
progress bar, so the bar's clock (and its ETA) starts after the compile. A warm cache costs nothing: no line,
no loading.
"""

from __future__ import annotations

import sys
import time

#: Seconds a cold compile took, measured with `NUMBA_CACHE_DIR` set to an empty folder and
#: `python -m mobman_env`, then `python -m policies` (numba 0.68.1, Python 3.11, 2026-12-04, on the development
#: machine: 2 cores shared with other jobs; on a busy machine it took up to 34 s and 22 s). Only the message
#: quotes them.
COMPILE_S = {"engine": 18.0, "controllers": 14.0}


def cold_parts() -> list[str]:
    """The parts ("engine", "controllers") with at least one kernel a call would compile."""
    from mobman_env import engine
    from mobman_env.kernel_cache import cold_kernels
    from policies.warm import KERNEL_MODULES

    cold = {"engine": cold_kernels(engine), "controllers": cold_kernels(*KERNEL_MODULES)}
    return [part for part, kernels in cold.items() if kernels]


def warm_kernels(announce: bool = True) -> float:
    """Compile the cold parts' kernels now (see the module docstring); with `announce`, one line on stderr before
    and one after. Returns the seconds spent (0.0 when numba's cache already held everything)."""
    parts = cold_parts()
    if not parts:
        return 0.0
    from mobman_env import engine
    from policies import warm

    if announce:
        about = sum(COMPILE_S[p] for p in parts)
        print(
            f"compiling the kernels once (about {about:.0f} s; numba caches them for every later run) ...",
            file=sys.stderr,
            flush=True,
        )
    t0 = time.perf_counter()
    if "engine" in parts:
        engine.warm()
    if "controllers" in parts:
        warm.warm()
    spent = time.perf_counter() - t0
    if announce:
        print(f"kernels compiled in {spent:.0f} s", file=sys.stderr, flush=True)
    return spent
