"""Partial updates: a patch is a nested dict merged into the current state, validated whole.

A patch never half-applies: the merged tree is validated as a new ``Scene``; on any error the
caller keeps the old state. Dicts merge key by key; lists and scalars replace.
"""

from __future__ import annotations

import json
from typing import Any

from .model import Scene


def deep_merge(base: dict, patch: dict) -> dict:
    out = dict(base)
    for key, value in patch.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = deep_merge(out[key], value)
        else:
            out[key] = value
    return out


def validate_wire(tree: Any) -> Scene:
    """A Scene from a decoded protocol message, with strict types: ``"10"`` is not a number, ``1`` not a bool.

    The tree holds JSON types only (the codec refuses the rest), so it is validated as JSON in pydantic's
    strict mode: the same rules for msgpack and JSON callers, and ISO strings still parse as times.
    TOML files and ``--set`` values are not wire input: they keep the lax ``Scene.model_validate``.
    """
    return Scene.model_validate_json(json.dumps(tree, allow_nan=False), strict=True)


def apply_patch(scene: Scene, patch: dict[str, Any], strict: bool = False) -> Scene:
    """Return a new validated Scene: ``scene`` with ``patch`` merged in. Raises pydantic.ValidationError.

    ``strict``: the patch came over the wire (see ``validate_wire``).
    """
    if not isinstance(patch, dict):
        raise TypeError("a patch must be an object")
    if strict:
        return validate_wire(deep_merge(scene.model_dump(mode="json"), patch))
    merged = deep_merge(scene.model_dump(mode="python"), patch)
    return Scene.model_validate(merged)


def parse_value(text: str) -> Any:
    """A ``--set`` value: JSON when it parses (numbers, true, [], {...}), else the raw string."""
    try:
        return json.loads(text)
    except ValueError:
        return text


def set_path(path: str, value: Any) -> dict[str, Any]:
    """``camera.pitch`` + 10 -> {"camera": {"pitch": 10}}."""
    keys = [k for k in path.split(".") if k]
    if not keys:
        raise ValueError(f"empty field path in {path!r}")
    patch: dict[str, Any] = {}
    node = patch
    for key in keys[:-1]:
        node[key] = {}
        node = node[key]
    node[keys[-1]] = value
    return patch


def patch_from_assignments(assignments: list[str]) -> dict[str, Any]:
    """Merge several ``PATH=VALUE`` strings into one patch."""
    patch: dict[str, Any] = {}
    for item in assignments:
        if "=" not in item:
            raise ValueError(f"expected PATH=VALUE, got {item!r}")
        path, text = item.split("=", 1)
        patch = deep_merge(patch, set_path(path.strip(), parse_value(text.strip())))
    return patch
