"""Partial updates: a patch is a nested dict merged into the current state, validated whole.

A patch never half-applies: the merged tree is validated as a new ``Scene``; on any error the
caller keeps the old state. Dicts merge key by key; lists and scalars replace.
"""

from __future__ import annotations

import copy
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
    # NaN/Infinity pass through as JSON's non-standard literals so the model reports them (finite_number)
    return Scene.model_validate_json(json.dumps(_integral_floats_as_ints(tree)), strict=True)


def _integral_floats_as_ints(node: Any) -> Any:
    """3.0 -> 3: JSON has one number type (JSON Schema calls 3.0 an integer), and strict mode would refuse it
    for an int field. Float fields take ints, so nothing else changes. (The codec bounded the depth.)"""
    if isinstance(node, float) and node.is_integer() and abs(node) < 2**53:
        return int(node)
    if isinstance(node, dict):
        return {key: _integral_floats_as_ints(value) for key, value in node.items()}
    if isinstance(node, list):
        return [_integral_floats_as_ints(value) for value in node]
    return node


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


def at_sim_time(scene: Scene, sim_time: float) -> Scene:
    """``scene`` at another ``time.sim_time``: the IG clock's step (an animating stream). Every other part
    of the state is the same object as before (a shallow copy, the value was validated by the clock),
    so what the renderer derives from them is found unchanged by identity, not compared field by field."""
    if scene.time.sim_time == sim_time:
        return scene
    return scene.model_copy(update={"time": scene.time.model_copy(update={"sim_time": sim_time})})


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


def _assign(tree: Any, keys: list[str], value: Any, path: str) -> None:
    """Set ``value`` at ``keys`` inside ``tree`` in place: maps by key (created when missing), lists by index."""
    node = tree
    for depth, key in enumerate(keys):
        last = depth == len(keys) - 1
        if isinstance(node, list):
            if not key.isdigit() or int(key) >= len(node):
                raise ValueError(f"{path}: {'.'.join(keys[:depth]) or 'the list'} has {len(node)} items; "
                                 f"{key!r} is not an index of it")
            if last:
                node[int(key)] = value
            else:
                node = node[int(key)]
        elif isinstance(node, dict):
            if last:
                node[key] = value
            else:
                node = node.setdefault(key, {})
        else:
            raise ValueError(f"{path}: {'.'.join(keys[:depth])} is a value, not a map or list")


def patch_from_assignments(assignments: list[str], base: dict[str, Any] | None = None) -> dict[str, Any]:
    """Merge several ``PATH=VALUE`` strings into one patch.

    A number in the path addresses a list item (``effects.0.active=false``). Lists replace whole in a patch,
    so such an assignment needs ``base`` (the current state as a plain tree): the patch then carries the
    whole list from ``base`` with that one item changed.
    """
    patch: dict[str, Any] = {}
    for item in assignments:
        if "=" not in item:
            raise ValueError(f"expected PATH=VALUE, got {item!r} (e.g. camera.pitch=10)")
        path, text = item.split("=", 1)
        path, value = path.strip(), parse_value(text.strip())
        keys = [k for k in path.split(".") if k]
        if not keys:
            raise ValueError(f"empty field path in {item!r}")
        list_at = next((i for i, k in enumerate(keys) if k.isdigit()), None)
        if list_at is None:
            patch = deep_merge(patch, set_path(path, value))
            continue
        if base is None:
            raise ValueError(f"{path}: list items need the current state to be addressed")
        view = copy.deepcopy(deep_merge(base, patch))
        _assign(view, keys, value, path)
        owner = view
        for key in keys[:list_at]:
            owner = owner[key]
        patch = deep_merge(patch, set_path(".".join(keys[:list_at]), owner))
    return patch
