"""Scene files (TOML): the same fields as the protocol, loaded into the same model."""

from __future__ import annotations

import tomllib

import tomli_w
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
    available = ", ".join(scene_names())
    raise FileNotFoundError(f"scene {str(name_or_path)!r} not found: not a file, nor one of the named scenes "
                            f"({available})")


def scene_names() -> list[str]:
    return sorted(p.stem for p in SCENES_DIR.glob("*.toml"))


def load_scene(name_or_path: str | Path) -> Scene:
    with open(resolve_scene_path(name_or_path), "rb") as fh:
        return Scene.model_validate(tomllib.load(fh))


def dumps_scene(scene: Scene) -> str:
    """TOML text for a scene (tables for sections, arrays of tables for effects/lights/entities), by tomli-w.

    tomli-w escapes every string (tabs, newlines, quotes) and writes times as TOML datetimes, so
    ``load_scene(save_scene(s)) == s``.
    """
    return tomli_w.dumps(scene.model_dump(mode="python", exclude_none=True))


def save_scene(scene: Scene, path: str | Path) -> None:
    Path(path).write_text(dumps_scene(scene))
