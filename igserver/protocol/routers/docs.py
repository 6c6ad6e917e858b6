"""Documentation of what OpenAPI cannot describe: the WebSocket protocol (a page and an AsyncAPI 3.0 document)."""

from __future__ import annotations

from functools import lru_cache
from html import escape
from typing import get_args

from fastapi import APIRouter
from fastapi.responses import HTMLResponse, JSONResponse

from ...scene.model import Scene
from ..models import AckMessage, CreditMessage, ErrorMessage, FrameMessage, HelloMessage, StateMessage
from ..problems import Problem
from . import ws

router = APIRouter(tags=["docs"])

REF = "#/components/schemas/{model}"
CLIENT_MESSAGES = (HelloMessage, StateMessage, AckMessage, CreditMessage)
SERVER_MESSAGES = (FrameMessage, ErrorMessage)


@lru_cache(maxsize=1)
def asyncapi_document() -> dict:
    schemas: dict = {}
    for model in (*CLIENT_MESSAGES, *SERVER_MESSAGES, Problem, Scene):
        schema = model.model_json_schema(ref_template=REF)
        for name, sub in schema.pop("$defs", {}).items():
            schemas.setdefault(name, sub)
        schemas[model.__name__] = schema
    messages = {
        model.__name__: {
            "name": model.__name__,
            "contentType": "application/vnd.msgpack",
            "summary": (model.__doc__ or "").strip().splitlines()[0],
            "payload": {"$ref": REF.format(model=model.__name__)},
        }
        for model in (*CLIENT_MESSAGES, *SERVER_MESSAGES)
    }
    refs = lambda models: [{"$ref": f"#/channels/frames/messages/{m.__name__}"} for m in models]  # noqa: E731
    return {
        "asyncapi": "3.0.0",
        "info": {
            "title": "igserver WebSocket /v1/ws",
            "version": "1",
            "description": (ws.__doc__ or "").strip(),
        },
        "servers": {"igserver": {"host": "127.0.0.1:8600", "protocol": "ws",
                                 "description": "binary msgpack messages both ways; bearer token when configured"}},
        "channels": {"frames": {"address": "/v1/ws", "messages": {n: {"$ref": f"#/components/messages/{n}"}
                                                                 for n in messages}}},
        "operations": {
            "sendToServer": {"action": "receive", "channel": {"$ref": "#/channels/frames"},
                             "summary": "what a client sends", "messages": refs(CLIENT_MESSAGES)},
            "receiveFromServer": {"action": "send", "channel": {"$ref": "#/channels/frames"},
                                  "summary": "what the server sends", "messages": refs(SERVER_MESSAGES)},
        },
        "components": {"messages": messages, "schemas": schemas},
    }


@router.get("/asyncapi.json", summary="The WebSocket protocol as an AsyncAPI 3.0 document")
async def asyncapi() -> JSONResponse:
    return JSONResponse(asyncapi_document())


@router.get("/v1/ws-protocol", response_class=HTMLResponse, summary="The WebSocket protocol, for people")
async def ws_protocol() -> HTMLResponse:
    rows = "".join(
        f"<tr><td>{direction}</td><td><code>{escape(' | '.join(get_args(m.model_fields['type'].annotation)))}"
        f"</code></td><td>{escape(', '.join(m.model_fields))}</td><td>{escape((m.__doc__ or '').strip())}</td></tr>"
        for direction, models in (("client → server", CLIENT_MESSAGES), ("server → client", SERVER_MESSAGES))
        for m in models
    )
    page = f"""<!doctype html><html><head><meta charset="utf-8"><title>igserver WebSocket protocol</title>
<style>body{{font-family:sans-serif;max-width:60em;margin:2em auto}}td,th{{border:1px solid #ccc;padding:4px}}
table{{border-collapse:collapse}}pre{{background:#f4f4f4;padding:1em}}</style></head><body>
<h1>WebSocket <code>/v1/ws</code></h1><pre>{escape((ws.__doc__ or '').strip())}</pre>
<table><tr><th>direction</th><th>type</th><th>fields</th><th>meaning</th></tr>{rows}</table>
<p>Schemas: <a href="/asyncapi.json">AsyncAPI 3.0 document</a> · REST: <a href="/docs">/docs</a></p>
</body></html>"""
    return HTMLResponse(page)
