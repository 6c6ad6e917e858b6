"""The IG clock: read it; run it free (real time, rate, pause, set) or hand it to the host.

``time.sim_time`` in any state message (PUT/PATCH /v1/state, POST /v1/render, the WebSocket) switches
the clock to ``host`` mode; ``PATCH /v1/clock {"mode": "free"}`` gives it back to the IG.
"""

from __future__ import annotations

from fastapi import APIRouter
from pydantic import ValidationError

from ..clock import ClockChange, ClockState
from ..dependencies import Message, ReplyFormat, Runtime, reply
from ..models import MSGPACK_ALSO, PROBLEM_RESPONSES, body_doc
from ..problems import ProblemError, from_validation_error

router = APIRouter(prefix="/v1/clock", tags=["clock"])


@router.get("", response_model=ClockState, summary="The IG clock: mode (free/host), sim_time, rate, paused",
            responses={200: {"content": MSGPACK_ALSO}})
async def get_clock(runtime: Runtime, fmt: ReplyFormat):
    return reply(runtime.clock.state().model_dump(), fmt)


@router.patch(
    "",
    response_model=ClockState,
    summary="Set the clock: mode, rate (sim s per real s), paused, sim_time (s); any subset",
    openapi_extra=body_doc(ClockChange.model_json_schema(), "a ClockChange: any subset of mode, rate, paused, sim_time"),
    responses={200: {"content": MSGPACK_ALSO}, **PROBLEM_RESPONSES},
)
async def patch_clock(runtime: Runtime, message: Message, fmt: ReplyFormat):
    if not isinstance(message, dict):
        raise ProblemError("validation", "a clock change must be a map", [{"pointer": "#", "detail": "expected a map"}])
    try:
        change = ClockChange.model_validate(message)
    except ValidationError as exc:
        raise from_validation_error(exc) from None
    runtime.clock.change(change)
    runtime.store.clock_changed()
    runtime.metrics.state_updates.inc(method="clock")
    return reply(runtime.clock.state().model_dump(), fmt)
