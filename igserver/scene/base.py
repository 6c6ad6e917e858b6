"""The base of every section of the scene model (unknown fields and non-finite floats refused) and the
field types the sections share: world coordinates, linear colours, ids."""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

# Upper bound on any world coordinate (m). 1e7 m is beyond a continent; float64 keeps mm there.
WORLD_LIMIT_M = 1.0e7

ID_PATTERN = r"^[A-Za-z0-9_.:-]{1,64}$"


class Strict(BaseModel):
    """Base: forbid unknown fields and non-finite floats, re-validate on assignment."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, validate_assignment=True)


Coordinate = Annotated[float, Field(ge=-WORLD_LIMIT_M, le=WORLD_LIMIT_M)]
Vec3 = tuple[Coordinate, Coordinate, Coordinate]
UnitColor = tuple[
    Annotated[float, Field(ge=0.0, le=1.0)],
    Annotated[float, Field(ge=0.0, le=1.0)],
    Annotated[float, Field(ge=0.0, le=1.0)],
]
EntityId = Annotated[str, Field(pattern=ID_PATTERN)]
