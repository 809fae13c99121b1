"""Command-line flags derived from a config dataclass: one flag per field, its help the field's docstring.

``--name`` for a field of the config, ``--part.name`` for a field of a nested config (``--sac.lr``,
``--reward.hidden``); the default shown is the preset's. A flag left out leaves the preset's value,
so a command that adds these flags runs exactly as before unless one is given.

Field docstrings (the string literal under a field) are read from the classes' source with
:mod:`ast`. Written here rather than taken from tyro or jsonargparse: both build whole parsers of
their own, whereas the learner commands are argparse subcommands that keep their hand-made flags
(``--steps``, ``--batch``, ``--teacher``…) and add these beside them; the module is the ~100
lines of that bridge (docs/own-method.md, "The command builder: why written here").
"""

from __future__ import annotations

import argparse
import ast
import dataclasses
import functools
import inspect
import textwrap

from ..sweeps.grid import with_field

PREFIX = "cfg:"
"""The namespace prefix of the derived flags' destinations (``cfg:sac.lr``)."""


@functools.cache
def field_docs(cls: type) -> dict[str, str]:
    """The docstring of each field of dataclass ``cls`` (its bases' too), first sentence-paragraph, one line."""
    docs: dict[str, str] = {}
    for klass in reversed(cls.__mro__):
        if not dataclasses.is_dataclass(klass):
            continue
        try:
            tree = ast.parse(textwrap.dedent(inspect.getsource(klass)))
        except (OSError, TypeError):
            continue
        body = tree.body[0].body
        for node, nxt in zip(body, body[1:]):
            if isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
                if (
                    isinstance(nxt, ast.Expr)
                    and isinstance(nxt.value, ast.Constant)
                    and isinstance(nxt.value.value, str)
                ):
                    docs[node.target.id] = " ".join(nxt.value.value.split("\n\n")[0].split())
    return docs


def _parser_of(annotation: str):
    """A flag's ``type`` from a field's annotation (a string under ``from __future__ import annotations``);
    None for a type the command line does not set."""
    text = annotation.replace(" ", "")
    optional = text.endswith("|None")
    base = text.removesuffix("|None")
    scalar = {"int": int, "float": float, "str": str}.get(base)
    if base.startswith("tuple[") and base.endswith(",...]"):
        item = {"int": int, "float": float, "str": str}.get(base[len("tuple[") : -len(",...]")])
        if item is None:
            return None
        scalar = lambda s, item=item: tuple(item(x) for x in s.split(",") if x)  # noqa: E731
    if scalar is None:
        return None
    if not optional:
        return scalar
    return lambda s: None if s.lower() == "none" else scalar(s)


def _shown(value) -> str:
    return ",".join(map(str, value)) if isinstance(value, tuple) else str(value)


def add_config_flags(
    p: argparse.ArgumentParser, cfg, *, skip: tuple[str, ...] = (), only: tuple[str, ...] = (), prefix: str = ""
) -> None:
    """A flag for every field of the config ``cfg`` (and of its nested configs), default ``cfg``'s.

    ``skip``: dotted field paths the command sets otherwise (its own flags, or fields it must not expose);
    ``only``: if given, the top-level fields that get flags.
    """
    docs = field_docs(type(cfg))
    group = p.add_argument_group(f"{type(cfg).__name__} fields" + (f" ({prefix.rstrip('.')})" if prefix else ""))
    for f in dataclasses.fields(cfg):
        path = prefix + f.name
        if path in skip or (only and not prefix and f.name not in only):
            continue
        value = getattr(cfg, f.name)
        if dataclasses.is_dataclass(value):
            add_config_flags(p, value, skip=skip, prefix=path + ".")
            continue
        doc = docs.get(f.name, "")
        flag = "--" + path.replace("_", "-")
        annotation = f.type if isinstance(f.type, str) else getattr(f.type, "__name__", "")
        if annotation.replace(" ", "") == "bool":
            group.add_argument(
                flag, dest=PREFIX + path, action=argparse.BooleanOptionalAction, default=argparse.SUPPRESS,
                help=f"{doc} (default: {'on' if value else 'off'})".replace("%", "%%"),
            )  # fmt: skip
            continue
        parse = _parser_of(annotation)
        if parse is None:
            continue
        group.add_argument(
            flag, dest=PREFIX + path, type=parse, default=argparse.SUPPRESS, metavar=f.name.upper(),
            help=f"{doc} (default: {_shown(value)})".replace("%", "%%"),
        )  # fmt: skip


def given(args: argparse.Namespace) -> dict:
    """The derived flags given on the command line: dotted field path → value."""
    return {k[len(PREFIX) :]: v for k, v in vars(args).items() if k.startswith(PREFIX)}


def with_flags(cfg, args: argparse.Namespace):
    """``cfg`` with the derived flags given on the command line applied (unchanged when none is)."""
    for path, value in given(args).items():
        cfg = with_field(cfg, path, value)
    return cfg
