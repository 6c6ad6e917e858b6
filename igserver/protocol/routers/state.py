"""The scene state: read it, replace it, merge a patch into it."""

from __future__ import annotations

from fastapi import APIRouter, Request

from ...scene.model import Scene
from ..dependencies import Message, ReplyFormat, Runtime, reply, wants_minimal
from ..models import MSGPACK_ALSO, PATCH_SCHEMA, PROBLEM_RESPONSES, SCENE_REF, Accepted, body_doc

router = APIRouter(prefix="/v1/state", tags=["state"])


def scene_tree(scene: Scene) -> dict:
    return scene.model_dump(mode="json")


def accepted_reply(request: Request, runtime, scene: Scene, fmt: str):
    headers = {"X-IG-Revision": str(runtime.store.revision), "X-IG-Host-Frame": str(scene.host_frame)}
    if wants_minimal(request):
        body = Accepted(revision=runtime.store.revision, host_frame=scene.host_frame).model_dump()
        return reply(body, fmt, headers=headers)
    return reply(scene_tree(scene), fmt, headers=headers)


@router.get("", response_model=Scene, summary="The current accepted state",
            responses={200: {"content": MSGPACK_ALSO}})
async def get_state(runtime: Runtime, fmt: ReplyFormat):
    scene = runtime.store.scene
    return reply(scene_tree(scene), fmt, headers={"X-IG-Revision": str(runtime.store.revision)})


@router.put(
    "",
    response_model=Scene,
    summary="Replace the whole state (omitted fields take their defaults)",
    openapi_extra=body_doc(SCENE_REF, "a complete Scene"),
    responses={200: {"content": MSGPACK_ALSO}, **PROBLEM_RESPONSES},
)
async def put_state(request: Request, runtime: Runtime, message: Message, fmt: ReplyFormat):
    scene = runtime.store.replace(message)
    runtime.metrics.state_updates.inc(method="put")
    return accepted_reply(request, runtime, scene, fmt)


@router.patch(
    "",
    response_model=Scene,
    summary="Merge a partial state into the current one",
    openapi_extra=body_doc(PATCH_SCHEMA, "a partial Scene"),
    responses={200: {"content": MSGPACK_ALSO}, **PROBLEM_RESPONSES},
)
async def patch_state(request: Request, runtime: Runtime, message: Message, fmt: ReplyFormat):
    scene = runtime.store.patch(message)
    runtime.metrics.state_updates.inc(method="patch")
    return accepted_reply(request, runtime, scene, fmt)
