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


def apply_patch(scene: Scene, patch: dict[str, Any]) -> Scene:
    """Return a new validated Scene: ``scene`` with ``patch`` merged in. Raises pydantic.ValidationError."""
    if not isinstance(patch, dict):
        raise TypeError("a patch must be an object")
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
