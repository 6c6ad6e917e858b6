"""Scene files (TOML): the same fields as the protocol, loaded into the same model."""

from __future__ import annotations

import tomllib
from pathlib import Path

from .model import Scene

SCENES_DIR = Path(__file__).resolve().parents[1] / "scenes"  # package data: igserver/scenes


def resolve_scene_path(name_or_path: str | Path) -> Path:
    """A path, or a bare name looked up in the project's ``scenes/`` folder (``demo`` -> scenes/demo.toml)."""
    path = Path(name_or_path)
    if path.exists():
        return path
    candidate = SCENES_DIR / f"{path.stem}.toml"
    if candidate.exists():
        return candidate
    raise FileNotFoundError(f"scene file not found: {name_or_path}")


def load_scene(name_or_path: str | Path) -> Scene:
    with open(resolve_scene_path(name_or_path), "rb") as fh:
        return Scene.model_validate(tomllib.load(fh))


def _toml_value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value)
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{k} = {_toml_value(v)}" for k, v in value.items() if v is not None) + " }"
    raise TypeError(f"cannot write {type(value).__name__} to TOML")


def dumps_scene(scene: Scene) -> str:
    """TOML text for a scene (tables for sections, arrays of tables for effects/lights/entities)."""
    data = scene.model_dump(mode="json", exclude_none=True)
    lines: list[str] = []
    for key, value in data.items():
        if not isinstance(value, (dict, list)):
            lines.append(f"{key} = {_toml_value(value)}")
    for key, value in data.items():
        if isinstance(value, dict):
            lines.append(f"\n[{key}]")
            lines += [f"{k} = {_toml_value(v)}" for k, v in value.items()]
        elif isinstance(value, list):
            for item in value:
                lines.append(f"\n[[{key}]]")
                lines += [f"{k} = {_toml_value(v)}" for k, v in item.items()]
    return "\n".join(lines) + "\n"


def save_scene(scene: Scene, path: str | Path) -> None:
    Path(path).write_text(dumps_scene(scene))
