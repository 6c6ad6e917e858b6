"""Host queries about the rendered world: the sea's height, normal and surface velocity at points.

``POST /v1/query/water-height`` with ``{"points": [[x, y], ...], "sim_time": t?}`` (ENU metres; sim_time
defaults to the current state's) answers ``{"sim_time", "height": [...], "normal": [[nx, ny, nz]...],
"velocity": [[vx, vy, vz]...]}`` (to 7 decimals: 0.1 µm): heights are ENU z (the ocean level included), computed on the CPU
with the very maths and bathymetry the water shader uses (igserver.water), independent of camera and
LOD. The same query travels over the WebSocket as ``{"type": "query", "query": "water-height", ...}``.
"""

from __future__ import annotations

from typing import Annotated

import numpy as np
from fastapi import APIRouter, Depends, Request
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from ...scene.model import WORLD_LIMIT_M, Scene
from ..dependencies import ReplyFormat, Runtime, decode_message, reply
from ..models import MSGPACK_ALSO, PROBLEM_RESPONSES, body_doc
from ..problems import ProblemError, from_validation_error

router = APIRouter(prefix="/v1/query", tags=["query"])

MAX_QUERY_POINTS = 10_000
REPLY_DECIMALS = 7  # m, m/s: answers rounded to 0.1 µm
# strict: numbers only (JSON true/"1" are not coordinates), ints accepted as floats
Coordinate = Annotated[float, Field(strict=True, ge=-WORLD_LIMIT_M, le=WORLD_LIMIT_M, allow_inf_nan=False)]


class WaterHeightQuery(BaseModel):
    model_config = ConfigDict(extra="forbid")

    points: list[tuple[Coordinate, Coordinate]] = Field(
        ..., min_length=1, max_length=MAX_QUERY_POINTS, description="ENU (x, y) in m")
    sim_time: float | None = Field(None, ge=0.0, le=1e12, allow_inf_nan=False, strict=True,
                                   description="s; None = the current state's sim_time")


async def query_body(request: Request, runtime: Runtime):
    """The body under the server's limits, with arrays as long as the body allows (an item takes at least
    a byte): more points than MAX_QUERY_POINTS is always this route's validation error (422, pointer
    #/points), never the generic array limit; only a body over the byte limit is 413."""
    limits = runtime.settings.limits
    return await decode_message(request, limits.model_copy(
        update={"max_array": max(limits.max_array, limits.max_body_bytes)}))


QueryMessage = Annotated[object, Depends(query_body)]


async def query_slot(runtime: Runtime):
    """One of the ``max_concurrent_queries`` slots, taken before the body is read: a query over the bound
    is refused without its body being held and decoded."""
    with runtime.queries.enter():
        yield


QuerySlot = Annotated[None, Depends(query_slot)]


class WaterHeightReply(BaseModel):
    sim_time: float
    height: list[float] = Field(description="m, ENU z of the sea surface above each point")
    normal: list[tuple[float, float, float]] = Field(description="unit surface normal (ENU)")
    velocity: list[tuple[float, float, float]] = Field(description="m/s, velocity of the surface particle")


def water_height(scene: Scene, tree, prefix: tuple = ()) -> dict:
    """Validate a water-height query against ``scene`` and answer it (raises ProblemError)."""
    try:
        query = WaterHeightQuery.model_validate(tree)
    except ValidationError as exc:
        raise from_validation_error(exc, prefix) from None
    t = scene.time.sim_time if query.sim_time is None else query.sim_time
    if not scene.ocean.enabled:
        raise ProblemError("conflict", "the scene has no sea (ocean.enabled is false)",
                           [{"pointer": "#/ocean/enabled", "detail": "false"}])
    from ...water import sea_surface

    sea = sea_surface(scene.ocean, scene.weather)
    result = sea.query(np.asarray(query.points, dtype=np.float64), t)
    # REPLY_DECIMALS: 0.1 µm (µm/s, 1e-7 of a unit normal), below the maths' own ~1e-6 m (float32
    # sines): a short decimal is half the JSON bytes and its formatting half the time of 17 digits
    return {"sim_time": t, "height": np.round(result["height"] + scene.ocean.level, REPLY_DECIMALS).tolist(),
            "normal": np.round(result["normal"], REPLY_DECIMALS).tolist(),
            "velocity": np.round(result["velocity"], REPLY_DECIMALS).tolist()}


@router.post(
    "/water-height",
    response_model=WaterHeightReply,
    summary="Sea surface height, normal and velocity at points (CPU, same maths as the renderer)",
    openapi_extra=body_doc(WaterHeightQuery.model_json_schema(), "points and optional sim_time"),
    responses={200: {"content": MSGPACK_ALSO}, **PROBLEM_RESPONSES},
)
async def query_water_height(runtime: Runtime, slot: QuerySlot, message: QueryMessage, fmt: ReplyFormat):
    return reply(await runtime.run_query(water_height, runtime.store.scene, message), fmt)


async def answer_water_height(runtime, tree, prefix: tuple = ()) -> dict:
    """``water_height`` on the runtime's query threads, at most ``max_concurrent_queries`` at once (more:
    ``overloaded``, 503 with Retry-After). The numpy work is off the event loop, so streams keep flowing;
    the bound keeps many big queries from taking the CPU from the render loop and their temporaries from
    piling up in memory."""
    with runtime.queries.enter():
        return await runtime.run_query(water_height, runtime.store.scene, tree, prefix)
