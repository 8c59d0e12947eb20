"""One look per controller across every plot: its colour from its spec, its line style from its knowledge class.

* `color_of(spec)`: a built-in name has a fixed colour (`BUILTIN_COLORS`); any other spec or label (options,
  `sb3:` agents, `module:attr`, a name given to `eval.run`) a colour of `OTHER_COLORS` chosen by a stable hash
  of the string (CRC-32: the same in every process and on every machine). `nnbc-plus` is orange in every figure.
* `linestyle_of(spec, knowledge)`: solid for class `none` (model-free), dash-dot for `structure`, dashed for
  `nominal`, dotted for `true` (the oracles), dash-dot-dot for `unknown` (`policies.knowledge`). The class is a
  record's `knowledge` field where it has one, else `policies.knowledge_of(spec)`; a label that names no
  importable policy is `unknown`.
* `tolerance_line(ax, tolerance_m)`: the success tolerance as a thin black line labelled "tolerance 6 mm"
  (it appears in the legend).

Every controller line carries `gid="policy:<spec>"`, so a test (or a reader of an SVG) can find it.

Imports matplotlib's colour helpers and `policies.knowledge`.
"""

from __future__ import annotations

import functools
import zlib
from typing import Any

from policies.knowledge import UNKNOWN, knowledge_of

#: The colour of every built-in policy name (`policies.KNOWN_POLICIES`): a family shares a hue, its `-full`
#: variant the light shade (matplotlib's tab10 / tab20 colours).
BUILTIN_COLORS: dict[str, str] = {
    "nnbc": "#9467bd",  # purple
    "nnbc-full": "#c5b0d5",
    "nnbc-plus": "#ff7f0e",  # orange
    "broyden": "#bcbd22",  # olive
    "rls": "#e377c2",  # pink
    "jmpi": "#2ca02c",  # green
    "jmpi-full": "#98df8a",
    "clik": "#d62728",  # red
    "clik-full": "#ff9896",
    "oracle": "#1f77b4",  # blue
    "oracle-full": "#aec7e8",
    "qp": "#8c564b",  # brown
    "qp-oracle": "#17becf",  # cyan
    "calib-qp": "#c49c94",  # light brown: the qp family's light shade (line style: its class, nominal)
    "mpc": "#f7b6d2",  # light pink (tab20's last free shade; dashed: class nominal)
    "mpc-oracle": "#9edae5",  # light cyan: qp-oracle's light shade (dotted, class true)
    "zero": "#7f7f7f",  # grey
    "random": "#c7c7c7",
}

#: The colours of every other spec (chosen by hash): dark or saturated shades far from the built-ins', so a
#: user's controller never looks like one: each is at least 28 (CIE76 Delta E in CIELAB) from every built-in
#: colour, from the black tolerance line and from the others (chosen greedily from ColorBrewer's dark shades).
OTHER_COLORS: tuple[str, ...] = (
    "#40004b",  # aubergine
    "#a6761d",  # dark gold
    "#637939",  # moss
    "#8e0152",  # wine
    "#1b9e77",  # teal
    "#e7298a",  # magenta
    "#08306b",  # navy
    "#01665e",  # dark teal
)

#: Line style of each knowledge class (`policies.knowledge.KNOWLEDGE_CLASSES` and "unknown").
LINESTYLES: dict[str, Any] = {
    "none": "-",
    "structure": "-.",
    "nominal": "--",
    "true": ":",
    UNKNOWN: (0, (3, 1, 1, 1, 1, 1)),
}

#: The tolerance line's colour (black: no controller's colour).
TOLERANCE_COLOR = "k"


def color_of(spec: str) -> str:
    """The colour of a policy spec or label: fixed for a built-in name, a stable hash into `OTHER_COLORS` else."""
    spec = str(spec)
    fixed = BUILTIN_COLORS.get(spec.strip())
    if fixed is not None:
        return fixed
    return OTHER_COLORS[zlib.crc32(spec.encode("utf-8")) % len(OTHER_COLORS)]


@functools.lru_cache(maxsize=256)
def _knowledge(spec: str) -> str:
    try:
        return knowledge_of(spec)
    except (ValueError, ImportError):  # a label naming no importable policy (e.g. a name given to eval.run)
        return UNKNOWN


def linestyle_of(spec: str, knowledge: str | None = None) -> Any:
    """The line style of the knowledge class `knowledge` (None: `policies.knowledge_of(spec)`)."""
    kind = knowledge if knowledge is not None else _knowledge(str(spec))
    if kind not in LINESTYLES:
        raise ValueError(f"knowledge class {kind!r} of {spec!r} has no line style; accepted: {', '.join(LINESTYLES)}")
    return LINESTYLES[kind]


def style_of(spec: str, knowledge: str | None = None) -> dict[str, Any]:
    """Keyword arguments of `Axes.plot` for a controller's line: colour, line style and the gid naming it."""
    return {"color": color_of(spec), "ls": linestyle_of(spec, knowledge), "gid": f"policy:{spec}"}


def record_style(row: dict) -> dict[str, Any]:
    """`style_of` a record or aggregate row: its `policy`, and its `knowledge` field where it has one."""
    return style_of(str(row["policy"]), row.get("knowledge"))


def tolerance_label(tolerance_m: float) -> str:
    """The legend text of the tolerance line: "tolerance 6 mm"."""
    return f"tolerance {tolerance_m * 1e3:g} mm"


def tolerance_line(ax: Any, tolerance_m: float, *, vertical: bool = False) -> Any:
    """Draw the success tolerance (m) on `ax` in mm: horizontal (an error axis) or vertical (a tolerance axis),
    labelled for the legend. Returns the Line2D."""
    draw = ax.axvline if vertical else ax.axhline
    return draw(tolerance_m * 1e3, color=TOLERANCE_COLOR, lw=0.8, ls="-", label=tolerance_label(tolerance_m))
