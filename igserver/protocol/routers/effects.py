"""Effects (fire, smoke, gas burners): add, change, activate and deactivate with a fade.

Each change goes through the state store, so it is validated as a whole scene, counted as a new
revision, and switching ``active`` stamps ``changed_at`` with the scene's sim_time (the fade start).
"""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Path, Query, Response

from ...scene.model import ID_PATTERN, MAX_EFFECTS, Effect
from ..dependencies import Message, ReplyFormat, Runtime, reply
from ..models import EFFECT_PATCH_REF, EFFECT_REF, MSGPACK_ALSO, PROBLEM_RESPONSES, QueryBool, body_doc
from ..problems import ProblemError, summary

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
    # errors point into the request body (``#/diameter``), not into the scene (``#/effects/3/diameter``),
    # in errors[] and in the detail alike
    try:
        runtime.store.patch({"effects": trees})
    except ProblemError as problem:
        if index_for_errors is not None:
            prefix = f"#/effects/{index_for_errors}"
            for error in problem.errors:
                if error["pointer"] == prefix or error["pointer"].startswith(prefix + "/"):
                    error["pointer"] = "#" + error["pointer"][len(prefix):]
            problem.detail = summary(problem.errors) if problem.errors else problem.detail
        raise
    runtime.metrics.state_updates.inc(method=method)


def _make_room(runtime, trees: list[dict], effect_id: str) -> list[dict]:
    """A new effect takes the place of a DELETEd one fading out under its id, and, when every slot is
    taken, those of DELETEd ones fading out (soonest gone first): their fades are cut short."""
    fading = runtime.store.fading_out()
    trees = [tree for tree in trees if not (tree["id"] == effect_id and tree["id"] in fading)]
    for fading_id in fading:
        if len(trees) < MAX_EFFECTS:
            break
        trees = [tree for tree in trees if tree["id"] != fading_id]
    return trees


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
    trees = _make_room(runtime, _effect_trees(runtime), message.get("id"))
    if any(tree["id"] == message.get("id") for tree in trees):
        raise ProblemError("conflict", f"effect {message.get('id')!r} exists: PATCH it instead")
    trees.append(message)
    _commit(runtime, trees, len(trees) - 1, "effect_add")
    runtime.store.keep(message["id"])
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
    summary="Deactivate with a fade, then remove (202: listed, inactive, until the fade ends; its id and "
    "slot are free at once); ?immediate=true removes it now (204)",
    responses={202: {"model": Effect, "content": MSGPACK_ALSO}, 204: {"description": "removed"}},
)
async def delete_effect(
    runtime: Runtime,
    fmt: ReplyFormat,
    effect_id: str = EffectId,
    immediate: Annotated[QueryBool, Query(description="remove at once, without a fade")] = False,
):
    index, trees = _find(runtime, effect_id)
    if immediate:
        del trees[index]
        _commit(runtime, trees, None, "effect_delete")
        return Response(status_code=204)
    trees[index]["active"] = False
    _commit(runtime, trees, index, "effect_deactivate")
    runtime.store.remove_after_fade(effect_id)
    index, trees = _find(runtime, effect_id)
    return reply(trees[index], fmt, status_code=202)
