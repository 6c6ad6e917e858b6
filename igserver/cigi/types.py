"""The entity-type mapping file: CIGI entity types -> models, part ids -> glTF node names, database
numbers -> scenes (igserver/cigi/entity_types.toml is the shipped default)."""

from __future__ import annotations

import tomllib
from functools import lru_cache
from pathlib import Path
from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

DEFAULT_FILE = Path(__file__).with_name("entity_types.toml")
Positive = Annotated[float, Field(gt=0.0, le=1e4)]


class EntityType(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)

    model: str = "box"
    scale: tuple[Positive, Positive, Positive] = (1.0, 1.0, 1.0)
    size: tuple[Positive, Positive, Positive] | None = Field(
        None, description="m, bounding box (width, length, height) for queries; None = scale (the box model)")
    parts: dict[str, str] = Field(default_factory=dict, description="articulated part id -> glTF node name")

    def bounds(self) -> tuple[float, float, float]:
        """m, (width along starboard, length along forward, height up) from the entity's origin."""
        return self.size or self.scale


class TypeMap(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)

    default: EntityType = Field(default_factory=EntityType)
    types: dict[str, EntityType] = Field(default_factory=dict)
    databases: dict[str, str] = Field(default_factory=dict)

    def entity_type(self, number: int) -> EntityType:
        return self.types.get(str(number), self.default)

    def database(self, number: int) -> str | None:
        return self.databases.get(str(number))


@lru_cache(maxsize=8)
def load_type_map(path: str | None = None) -> TypeMap:
    """The mapping in ``path`` (the shipped default when None); raises ValueError with the file's name."""
    source = Path(path) if path else DEFAULT_FILE
    try:
        with open(source, "rb") as f:
            return TypeMap.model_validate(tomllib.load(f))
    except (OSError, tomllib.TOMLDecodeError, ValueError) as exc:
        raise ValueError(f"CIGI entity-type file {source}: {exc}") from None
