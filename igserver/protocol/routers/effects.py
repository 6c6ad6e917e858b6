"""Effects (fire, smoke, gas burners): add, change, activate and deactivate with a fade.

Each change goes through the state store, so it is validated as a whole scene, counted as a new
revision, and switching ``active`` stamps ``changed_at`` with the scene's sim_time (the fade start).
"""

from __future__ import annotations

from fastapi import APIRouter, Path, Query, Response

from ...scene.model import ID_PATTERN, Effect
from ..dependencies import Message, ReplyFormat, Runtime, reply
from ..models import EFFECT_PATCH_REF, EFFECT_REF, MSGPACK_ALSO, PROBLEM_RESPONSES, body_doc
from ..problems import ProblemError

router = APIRouter(prefix="/v1/effects", tags=["effects"])

EffectId = Path(..., pattern=ID_PATTERN, description="effect id")


def _effect_trees(runtime) -> list[dict]:
    return [effect.model_dump(mode="json") for effect in runtime.store.scene.effects]


def _find(runtime, effect_id: str) -> tuple[int, list[dict]]:
    trees = _effect_trees(runtime)
    for index, tree in enumerate(trees):
        if tree["id"] == effect_id:
            return index, trees
    raise ProblemError("not_found", f"no effect {effect_id!r}")


def _commit(runtime, trees: list[dict], index_for_errors: int | None, method: str) -> None:
    # errors point into the request body (``#/diameter``), not into the scene (``#/effects/3/diameter``)
    try:
        runtime.store.patch({"effects": trees})
    except ProblemError as problem:
        prefix = f"#/effects/{index_for_errors}" if index_for_errors is not None else None
        if prefix:
            for error in problem.errors:
                if error["pointer"].startswith(prefix):
                    error["pointer"] = "#" + error["pointer"][len(prefix):]
        raise
    runtime.metrics.state_updates.inc(method=method)


@router.get("", response_model=list[Effect], summary="All effects", responses={200: {"content": MSGPACK_ALSO}})
async def list_effects(runtime: Runtime, fmt: ReplyFormat):
    return reply(_effect_trees(runtime), fmt)


@router.post(
    "",
    status_code=201,
    response_model=Effect,
    summary="Add an effect (active effects fade in from now)",
    openapi_extra=body_doc(EFFECT_REF, "an Effect"),
    responses={201: {"content": MSGPACK_ALSO}, 409: {"description": "an effect with this id exists"},
               **PROBLEM_RESPONSES},
)
async def add_effect(runtime: Runtime, message: Message, fmt: ReplyFormat):
    if not isinstance(message, dict):
        raise ProblemError("validation", "an effect must be a map", [{"pointer": "#", "detail": "expected a map"}])
    trees = _effect_trees(runtime)
    if any(tree["id"] == message.get("id") for tree in trees):
        raise ProblemError("conflict", f"effect {message.get('id')!r} exists: PATCH it instead")
    trees.append(message)
    _commit(runtime, trees, len(trees) - 1, "effect_add")
    _, trees = _find(runtime, message["id"])
    effect = next(t for t in trees if t["id"] == message["id"])
    return reply(effect, fmt, status_code=201, headers={"Location": f"/v1/effects/{message['id']}"})


@router.get("/{effect_id}", response_model=Effect, summary="One effect", responses={200: {"content": MSGPACK_ALSO}})
async def get_effect(runtime: Runtime, fmt: ReplyFormat, effect_id: str = EffectId):
    index, trees = _find(runtime, effect_id)
    return reply(trees[index], fmt)


@router.patch(
    "/{effect_id}",
    response_model=Effect,
    summary="Change an effect; {\"active\": false} extinguishes it with a fade, {\"active\": true} reignites",
    openapi_extra=body_doc(EFFECT_PATCH_REF, "a partial Effect"),
    responses={200: {"content": MSGPACK_ALSO}, **PROBLEM_RESPONSES},
)
async def patch_effect(runtime: Runtime, message: Message, fmt: ReplyFormat, effect_id: str = EffectId):
    if not isinstance(message, dict):
        raise ProblemError("validation", "a patch must be a map", [{"pointer": "#", "detail": "expected a map"}])
    if "id" in message and message["id"] != effect_id:
        raise ProblemError("validation", "an effect's id cannot change",
                           [{"pointer": "#/id", "detail": "must equal the id in the path"}])
    index, trees = _find(runtime, effect_id)
    trees[index] = {**trees[index], **message}
    _commit(runtime, trees, index, "effect_patch")
    index, trees = _find(runtime, effect_id)
    return reply(trees[index], fmt)


@router.delete(
    "/{effect_id}",
    status_code=202,
    summary="Deactivate with a fade (202, the effect stays until replaced); ?immediate=true removes it (204)",
    responses={202: {"model": Effect, "content": MSGPACK_ALSO}, 204: {"description": "removed"}},
)
async def delete_effect(
    runtime: Runtime,
    fmt: ReplyFormat,
    effect_id: str = EffectId,
    immediate: bool = Query(False, description="remove at once, without a fade"),
):
    index, trees = _find(runtime, effect_id)
    if immediate:
        del trees[index]
        _commit(runtime, trees, None, "effect_delete")
        return Response(status_code=204)
    trees[index]["active"] = False
    _commit(runtime, trees, index, "effect_deactivate")
    index, trees = _find(runtime, effect_id)
    return reply(trees[index], fmt, status_code=202)
