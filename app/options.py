"""Command-line options derived from config dataclasses, so each option's flag, type, default and help live once.

A field joins the command line when its metadata holds "help"; its flag is the field's name with dashes unless the
metadata names one ("flag"). Other metadata: "choices", "metavar", "required", and "comma" (a tuple given as one
comma-separated value). A bool field is a switch: "--x" when it defaults to False, "--no-x" (its "flag") when True.
Written here rather than taken from tyro, whose usage errors are multi-line panels: every refusal is one line, exit 2.
"""

from __future__ import annotations

import argparse
import dataclasses
from typing import Any

# The annotation of a field (a string: `from __future__ import annotations`) -> the type its option parses.
SCALARS = {"int": int, "float": float, "str": str, "int | None": int, "str | None": str, "float | None": float}


def add_options(parser: argparse.ArgumentParser, config_type: type) -> None:
    """Add an option for every field of `config_type` that has help in its metadata."""
    for f in dataclasses.fields(config_type):
        if "help" in f.metadata:
            parser.add_argument(*_flags(f), **_argument(f))


def config_from(config_type: type, args: argparse.Namespace, **values: Any) -> Any:
    """A `config_type` of the parsed options its fields declared, and `values` for the others."""
    chosen = {f.name: _value(f, getattr(args, f.name)) for f in dataclasses.fields(config_type)
              if "help" in f.metadata and f.name not in values}
    return config_type(**chosen, **values)


def _flags(f: dataclasses.Field) -> list[str]:
    return [f.metadata.get("flag") or "--" + f.name.replace("_", "-")]


def _default(f: dataclasses.Field) -> Any:
    if f.default is not dataclasses.MISSING:
        return f.default
    return None if f.default_factory is dataclasses.MISSING else f.default_factory()


def _argument(f: dataclasses.Field) -> dict[str, Any]:
    """argparse's keywords for field `f`."""
    meta, default = f.metadata, _default(f)
    kwargs: dict[str, Any] = {"dest": f.name, "help": meta["help"]}
    if f.type == "bool":
        return kwargs | {"action": "store_false" if default else "store_true", "default": default}
    if meta.get("required"):
        kwargs["required"] = True
    else:
        kwargs["default"] = ",".join(default) if meta.get("comma") else default
    if f.type.startswith("tuple") and not meta.get("comma"):
        kwargs["nargs"] = "+"
    elif f.type in SCALARS:
        kwargs["type"] = SCALARS[f.type]
    for key in ("choices", "metavar"):
        if key in meta:
            kwargs[key] = meta[key]
    if "flag" in meta and "metavar" not in kwargs and "choices" not in kwargs:
        kwargs["metavar"] = meta["flag"].lstrip("-").replace("-", "_").upper()  # as argparse names its own flags
    return kwargs


def _value(f: dataclasses.Field, parsed: Any) -> Any:
    """The field's value from what argparse parsed (a comma list split, a list made a tuple)."""
    if f.metadata.get("comma"):
        return tuple(item.strip() for item in parsed.split(",") if item.strip())
    return tuple(parsed) if isinstance(parsed, list) else parsed
