"""Command-line options generated from config dataclasses: one option per field, whose help is the field's
docstring and whose default is the field's default, so the code and `--help` cannot drift (STYLE 8).

`Opt` says only what a field's type and docstring cannot: the option's name when it is not `--field-name`, a
metavar, how one value is parsed, the accepted values, text added after the docstring, and the old spellings
still accepted for one release (each use prints a deprecation message naming the new spelling on stderr). The
kind of option follows from the field's type:

* `bool` with default False: a flag (`--video`); with default True: a flag that turns it off (`--no-plots`,
  `--quiet`);
* `int`, `float`, `str` (or `X | None`): one value;
* `tuple[X, ...]`: repeatable, and each value may be a comma list (`--policy nnbc --policy jmpi,oracle`);
* `dict` / `Mapping`: a JSON object (`--env-kwargs '{"path": {"type": "circle"}}'`).

An option not given is absent from the parsed namespace (`argparse.SUPPRESS`): `given(args, opts)` is what the
command line set, and `build(cls, args, opts)` fills in the rest from the dataclass's own defaults. Every action
added here carries its field (`field_of(action)`), which `tests/test_cli_options.py` uses to compare every
option of every subcommand with its field.
"""

from __future__ import annotations

import argparse
import ast
import dataclasses
import functools
import inspect
import itertools
import json
import sys
import textwrap
import types
import typing
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

#: the attribute of an argparse action naming its dataclass field: (class, field name)
FIELD_ATTR = "config_field"


@dataclass(frozen=True)
class Opt:
    """How one field of a config dataclass appears on the command line (the rest comes from the field)."""

    field: str
    """The field's name."""
    flag: str | None = None
    """The option; None: `--field-name`. For a bool field whose default is True, the flag that turns it off."""
    metavar: str | None = None
    """The value's name in the help; None: the flag's name in capitals."""
    parse: Callable[[str], Any] | None = None
    """One value (one item of a list) from its text; None: from the field's type."""
    split: Callable[[str], list[str]] | None = None
    """List fields: one command-line value -> its items; None: split at commas."""
    choices: Sequence[Any] | None = None
    """The accepted values (of each item, for a list)."""
    more: str | Callable[[], str] | None = None
    """Text after the docstring (e.g. the accepted values read from a registry)."""
    old: tuple[str, ...] = ()
    """Earlier spellings, accepted for one release with a deprecation message naming `flag`."""
    positional: bool = False
    """A positional argument (list fields: any number of them; at least one when the field has no default)."""


def commas(text: str) -> list[str]:
    """`a, b,c` -> ["a", "b", "c"] (empty pieces dropped, so "" is the empty list)."""
    return [v.strip() for v in text.split(",") if v.strip()]


def policy_list(text: str) -> list[str]:
    """Comma-separated policy specs; a piece `key=value` without a name continues the spec before it, so
    `nnbc:gamma=20,mu=20,jmpi` is two specs: `nnbc:gamma=20,mu=20` and `jmpi`."""
    specs: list[str] = []
    for piece in commas(text):
        if specs and "=" in piece and ":" not in piece and ":" in specs[-1]:
            specs[-1] += "," + piece
        else:
            specs.append(piece)
    return specs


#: an example of --env-kwargs, in its messages
ENV_KWARGS_EXAMPLE = '\'{"path": {"type": "circle", "duration": 2.0}}\''


def json_object(text: str, option: str = "--env-kwargs") -> dict:
    """A JSON object from the command line; ArgumentTypeError names the option, the value and the form."""
    form = f"{option} must be a JSON object such as {ENV_KWARGS_EXAMPLE}"
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        raise argparse.ArgumentTypeError(f"{form}; {text!r} is not valid JSON ({exc})") from None
    if not isinstance(value, dict):
        raise argparse.ArgumentTypeError(f"{form}; got {text!r}")
    return value


@functools.cache
def field_docs(cls: type) -> dict[str, str]:
    """{field name: its docstring, whitespace collapsed} of a dataclass, read from the source: the string
    literal right under each annotated attribute (cleanrl's style; `inspect` cannot see them)."""
    tree = ast.parse(textwrap.dedent(inspect.getsource(cls)))
    body = next(n for n in tree.body if isinstance(n, ast.ClassDef)).body
    docs: dict[str, str] = {}
    for node, after in itertools.pairwise(body):
        if (
            isinstance(node, ast.AnnAssign)
            and isinstance(node.target, ast.Name)
            and isinstance(after, ast.Expr)
            and isinstance(after.value, ast.Constant)
            and isinstance(after.value.value, str)
        ):
            docs[node.target.id] = " ".join(after.value.value.split())
    return docs


def field_default(cls: type, name: str) -> Any:
    """The default of field `name` of the dataclass `cls` (a fresh one for a default factory)."""
    f = {f.name: f for f in dataclasses.fields(cls)}[name]
    if f.default is not dataclasses.MISSING:
        return f.default
    if f.default_factory is not dataclasses.MISSING:
        return f.default_factory()
    raise KeyError(f"{cls.__name__}.{name} has no default")


def _field_type(cls: type, name: str) -> tuple[Any, bool]:
    """(the field's type without `| None`, whether None is allowed)."""
    hint = typing.get_type_hints(cls)[name]
    args = typing.get_args(hint)
    if typing.get_origin(hint) in (typing.Union, types.UnionType) and type(None) in args:
        rest = [a for a in args if a is not type(None)]
        return (rest[0] if len(rest) == 1 else hint), True
    return hint, False


def _kind(hint: Any) -> str:
    origin = typing.get_origin(hint) or hint
    if hint is bool:
        return "flag"
    if origin is tuple:
        return "list"
    if origin in (dict, Mapping) or hint is dict:
        return "json"
    return "value"


def flag_of(opt: Opt | str) -> str:
    """The option of `opt` (`--field-name` unless it names its own)."""
    opt = _opt(opt)
    return opt.flag or "--" + opt.field.replace("_", "-")


def flags(opts: Iterable[Opt | str]) -> dict[str, str]:
    """{field: its option} of `opts` (e.g. to name what the command line gave in a message)."""
    return {_opt(o).field: flag_of(o) for o in opts}


def show_default(value: Any) -> str | None:
    """How a default reads in the help; None: not shown (None, False and empty values are said by the docstring)."""
    if value is None or value is False or (isinstance(value, (tuple, list, dict)) and not value):
        return None
    if isinstance(value, (tuple, list)):
        return ",".join(str(v) for v in value)
    if isinstance(value, dict):
        return json.dumps(value)
    return str(value)


def help_text(cls: type, opt: Opt) -> str:
    """The option's help: the field's docstring, what `opt.more` adds, how a list or a switch-off flag is given,
    and the field's default."""
    doc = field_docs(cls).get(opt.field)
    if not doc:
        raise KeyError(f"{cls.__name__}.{opt.field} has no docstring: write one under the field (it is the --help)")
    hint, _ = _field_type(cls, opt.field)
    default = None if _required(cls, opt.field) else field_default(cls, opt.field)
    parts = [doc]
    kind = _kind(hint)
    if kind == "list" and not opt.positional:
        parts.append("Repeatable; a value may be a comma list.")
    if kind == "flag" and default is True:
        parts.append("On by default; this flag turns it off.")
    shown = show_default(default) if kind != "flag" else None
    if shown is not None:
        parts.append(f"(default: {shown})")
    if opt.more:
        parts.append(opt.more() if callable(opt.more) else opt.more)
    return " ".join(parts).replace("%", "%%")


class _Value(argparse.Action):
    """One value (the last given wins); prints the deprecation message when given by an old spelling."""

    def __init__(self, *args: Any, renamed_to: str | None = None, **kwargs: Any):
        super().__init__(*args, **kwargs)
        self.renamed_to = renamed_to

    def warn(self, parser: argparse.ArgumentParser, option_string: str | None) -> None:
        if self.renamed_to is not None and option_string is not None:
            same = "" if self.nargs == 0 else " (same values)"
            deprecated(parser.prog, f"{option_string} is now {self.renamed_to}{same}")

    def __call__(self, parser, namespace, values, option_string=None):
        self.warn(parser, option_string)
        setattr(namespace, self.dest, values)


class _Extend(_Value):
    """A list: every use adds its items (the type function turns one value into a list of items; a positional
    argument gets one such list per value)."""

    def __call__(self, parser, namespace, values, option_string=None):
        self.warn(parser, option_string)
        items = list(getattr(namespace, self.dest, None) or [])
        for value in values if self.nargs in ("*", "+") else [values]:
            items.extend(value)
        setattr(namespace, self.dest, items)


class _Flag(_Value):
    """A switch: sets its constant (True, or False for a flag that turns a default-on field off)."""

    def __init__(self, *args: Any, **kwargs: Any):
        super().__init__(*args, nargs=0, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None):
        self.warn(parser, option_string)
        setattr(namespace, self.dest, self.const)


def deprecated(prog: str, message: str) -> None:
    """The one form of a deprecation message on stderr (old spellings work for one release)."""
    print(f"{prog}: DeprecationWarning: {message}; the old spelling goes in the next release", file=sys.stderr)


def _items(parse: Callable[[str], Any], split: Callable[[str], list[str]], choices: Sequence[Any] | None, what: str):
    """The type function of a list option: split one value, parse and check each item."""

    def items(text: str) -> list:
        out = []
        for piece in split(text):
            value = parse(piece)
            if choices is not None and value not in choices:
                raise argparse.ArgumentTypeError(
                    f"unknown {what} {piece!r} in {text!r}; accepted: {', '.join(map(str, choices))}"
                )
            out.append(value)
        return out

    items.__name__ = what  # argparse's "invalid <name> value" messages
    return items


def add_options(parser: argparse.ArgumentParser | Any, cls: type, opts: Iterable[Opt | str]) -> None:
    """Add one option per `Opt` (a bare name is `Opt(name)`) of the dataclass `cls` to `parser` (or an argument
    group), generated from the field: name, kind, help and default."""
    for opt in map(_opt, opts):
        hint, _ = _field_type(cls, opt.field)
        kind = _kind(hint)
        flag = flag_of(opt)
        kw: dict[str, Any] = {"dest": opt.field, "help": help_text(cls, opt)}
        if kind == "flag":
            default = field_default(cls, opt.field)
            kw.update(action=_Flag, const=not default, default=argparse.SUPPRESS)
        else:
            metavar = opt.metavar or (
                "{" + ",".join(map(str, opt.choices)) + "}"
                if opt.choices
                else flag.lstrip("-").replace("-", "_").upper()
            )
            if kind == "list":
                item = (typing.get_args(hint) or (str,))[0]
                parse = opt.parse or _scalar(item)
                what = flag.lstrip("-").replace("-", " ")
                split = opt.split or ((lambda text: [text]) if opt.positional else commas)
                kw.update(action=_Extend, type=_items(parse, split, opt.choices, what), metavar=metavar)
            elif kind == "json":
                kw.update(action=_Value, type=opt.parse or json_object, metavar=metavar)
            else:
                kw.update(action=_Value, type=opt.parse or _scalar(hint), metavar=metavar, choices=opt.choices)
            kw["default"] = argparse.SUPPRESS
        if opt.positional:
            kw.pop("dest")
            kw["nargs"] = "+" if _required(cls, opt.field) else "*"
            action = parser.add_argument(opt.field, **kw)
        else:
            action = parser.add_argument(flag, **kw)
        setattr(action, FIELD_ATTR, (cls, opt.field))
        if opt.old:
            hidden = {**kw, "help": argparse.SUPPRESS, "renamed_to": flag}
            parser.add_argument(*opt.old, **hidden)


def _required(cls: type, name: str) -> bool:
    f = {f.name: f for f in dataclasses.fields(cls)}[name]
    return f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING


def _scalar(hint: Any) -> Callable[[str], Any]:
    if hint in (int, float, str):
        return hint
    raise TypeError(f"no parser for a field of type {hint!r}: give Opt(parse=...)")


def _opt(o: Opt | str) -> Opt:
    return o if isinstance(o, Opt) else Opt(o)


def given(args: argparse.Namespace, opts: Iterable[Opt | str]) -> dict[str, Any]:
    """{field: value} of the options of `opts` the command line gave (lists as tuples)."""
    values = vars(args)
    out = {}
    for opt in map(_opt, opts):
        if opt.field in values:
            v = values[opt.field]
            out[opt.field] = tuple(v) if isinstance(v, list) else v
    return out


def values(args: argparse.Namespace, cls: type, opts: Iterable[Opt | str]) -> dict[str, Any]:
    """{field: value} of every option of `opts`: what the command line gave, else the field's default in `cls`
    (for keyword arguments documented by a dataclass, e.g. `EvalConfig.workers` of `run_sweep`)."""
    listed = [_opt(o) for o in opts]
    return {**{o.field: field_default(cls, o.field) for o in listed}, **given(args, listed)}


def build(cls: type, args: argparse.Namespace, opts: Iterable[Opt | str], **fixed: Any) -> Any:
    """The dataclass `cls` from what the command line gave of `opts` (the rest: its defaults) and `fixed`."""
    return cls(**{**given(args, opts), **fixed})


def field_of(action: argparse.Action) -> tuple[type, str] | None:
    """(dataclass, field) of an action added by `add_options`; None for argparse's own (-h, --version)."""
    return getattr(action, FIELD_ATTR, None)
