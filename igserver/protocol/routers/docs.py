"""Documentation pages: the WebSocket protocol (a page and an AsyncAPI 3.0 document), ReDoc, the favicon.

Every page works on an air-gapped network and loads nothing from elsewhere: Swagger UI and ReDoc come
from the fastapi-offline package, and ReDoc's bundle is served with its footer logo (an image it would
fetch from a CDN) pointed at the server's own icon.
"""

from __future__ import annotations

from functools import lru_cache
from html import escape
from pathlib import Path
from typing import get_args

from fastapi import APIRouter
from fastapi.openapi.docs import get_redoc_html
from fastapi.responses import HTMLResponse, JSONResponse, Response

from ...scene.model import Scene
from ..models import (AckMessage, ChannelsFrameMessage, CreditMessage, ErrorMessage, FrameMessage, HelloMessage,
                      StateMessage)
from ..problems import Problem
from . import ws

router = APIRouter(tags=["docs"])

REF = "#/components/schemas/{model}"
CLIENT_MESSAGES = (HelloMessage, StateMessage, AckMessage, CreditMessage)
SERVER_MESSAGES = (FrameMessage, ChannelsFrameMessage, ErrorMessage)


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


REDOC_LOGO = "https://cdn.redoc.ly/redoc/logo-mini.svg"
REDOC_BUNDLE = "/redoc/redoc.standalone.js"
FAVICON = "/favicon.ico"
STATIC_CACHE = {"Cache-Control": "public, max-age=86400"}


@lru_cache(maxsize=1)
def redoc_bundle() -> bytes:
    import fastapi_offline

    bundle = (Path(fastapi_offline.__file__).parent / "static" / "redoc.standalone.js").read_text(encoding="utf-8")
    return bundle.replace(REDOC_LOGO, FAVICON).encode("utf-8")


@router.get("/redoc", include_in_schema=False)
async def redoc() -> HTMLResponse:
    return get_redoc_html(openapi_url="/openapi.json", title="igserver - ReDoc", redoc_js_url=REDOC_BUNDLE,
                          redoc_favicon_url=FAVICON, with_google_fonts=False)


@router.get(REDOC_BUNDLE, include_in_schema=False)
async def redoc_js() -> Response:
    return Response(redoc_bundle(), media_type="text/javascript", headers=STATIC_CACHE)


@lru_cache(maxsize=1)
def favicon_ico() -> bytes:
    """A 32 px horizon: sky over sea, with a sun low over it (drawn once; ~1 KB)."""
    import io

    from PIL import Image, ImageDraw

    size = 32
    image = Image.new("RGBA", (size, size))
    draw = ImageDraw.Draw(image)
    for y in range(size):
        t = y / (size - 1)
        colour = (int(40 + 190 * t), int(90 + 90 * t), int(170 - 40 * t)) if y < 20 else (20, 60, 100)
        draw.line([(0, y), (size - 1, y)], fill=(*colour, 255))
    draw.ellipse([19, 11, 27, 19], fill=(255, 214, 120, 255))
    draw.rectangle([0, 20, size - 1, size - 1], fill=(20, 60, 100, 255))
    out = io.BytesIO()
    image.save(out, format="ICO", sizes=[(size, size)])
    return out.getvalue()


@router.get(FAVICON, include_in_schema=False)
async def favicon() -> Response:
    return Response(favicon_ico(), media_type="image/x-icon", headers=STATIC_CACHE)
