"""Progress bars on stderr (tqdm): redrawn on a terminal, one line every 5 s in a log file, none when disabled.
Stdout stays free for the results (`mobman-eval run --format json | jq`)."""

from __future__ import annotations

import sys
from typing import Any


def progress_bar(total: int, desc: str, unit: str, enabled: bool = True) -> Any:
    """A tqdm bar on stderr, or None when not `enabled`."""
    if not enabled:
        return None
    from tqdm import tqdm

    tty = hasattr(sys.stderr, "isatty") and sys.stderr.isatty()
    return tqdm(total=total, desc=desc, unit=unit, file=sys.stderr, dynamic_ncols=True, mininterval=0.1 if tty else 5.0)
