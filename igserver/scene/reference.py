"""The scene-format reference (docs/scene-format.md), generated from the model itself so the
documentation cannot drift from what the protocol and the scene files accept."""

from __future__ import annotations

import types
import typing

from annotated_types import Ge, Gt, Le, Lt, MaxLen
from pydantic import BaseModel

from .model import Scene


def _range(metadata) -> str:
    lo = hi = ""
    for m in metadata:
        if isinstance(m, Ge):
            lo = f"≥ {m.ge:g}"
        elif isinstance(m, Gt):
            lo = f"> {m.gt:g}"
        elif isinstance(m, Le):
            hi = f"≤ {m.le:g}"
        elif isinstance(m, Lt):
            hi = f"< {m.lt:g}"
        elif isinstance(m, MaxLen):
            hi = f"at most {m.max_length} items"
    return ", ".join(x for x in (lo, hi) if x)


def _model_of(annotation):
    for arg in (typing.get_args(annotation) or (annotation,)):
        if isinstance(arg, type) and issubclass(arg, BaseModel):
            return arg
        inner = typing.get_args(arg)
        for a in inner:
            if isinstance(a, type) and issubclass(a, BaseModel):
                return a
    return None


def _type_name(annotation) -> str:
    origin = typing.get_origin(annotation)
    if origin is typing.Literal:
        return " \\| ".join(f"`{a}`" for a in typing.get_args(annotation))
    if origin in (typing.Union, types.UnionType):
        return " or ".join(_type_name(a) for a in typing.get_args(annotation))
    if origin in (list, tuple):
        args = typing.get_args(annotation)
        inner = typing.get_origin(args[0]) is typing.Annotated and typing.get_args(args[0])[0] or args[0]
        return f"{origin.__name__}[{getattr(inner, '__name__', str(inner))}" + (", …]" if len(args) > 1 else "]")
    if annotation is type(None):
        return "null"
    return getattr(annotation, "__name__", str(annotation))


def _rows(model: type[BaseModel], prefix: str, rows: list[str]) -> None:
    sub = []
    for name, info in model.model_fields.items():
        path = f"{prefix}{name}"
        nested = _model_of(info.annotation)
        default = info.get_default(call_default_factory=False) if info.default_factory is None else "…"
        if nested is not None:
            sub.append((path, nested, info))
            if typing.get_origin(info.annotation) not in (list, dict):
                continue
        desc = (info.description or "").replace("|", "\\|")
        default_text = "required" if info.is_required() else f"`{default}`"
        rows.append(f"| `{path}` | {_type_name(info.annotation)} | {default_text} | {_range(info.metadata)} | {desc} |")
    for path, nested, info in sub:
        origin = typing.get_origin(info.annotation)
        suffix = "[]." if origin is list else ".<name>." if origin is dict else "."
        _rows(nested, path + suffix, rows)


def markdown_reference() -> str:
    rows = ["| field | type | default | range | unit and meaning |", "|---|---|---|---|---|"]
    _rows(Scene, "", rows)
    return "# Scene format reference\n\nGenerated from the scene model (`igserver/scene/`: `Scene` in `model.py`, a module per section) by " \
           "`python -m igserver.scene.reference > docs/scene-format.md`; a test keeps it current.\n\n" + "\n".join(rows) + "\n"


if __name__ == "__main__":
    print(markdown_reference(), end="")
