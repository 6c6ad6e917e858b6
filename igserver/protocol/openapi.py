"""The OpenAPI document, made to match the wire.

FastAPI describes what it can see: routes that decode their own msgpack/JSON bodies, answer every error as
an RFC 9457 problem (never FastAPI's ``HTTPValidationError``) and set headers by hand need the rest said
here: the problem schema on every 4xx/5xx (and as ``default``), the partial scene (``ScenePatch``) for
PATCH-style bodies, the ``X-IG-*`` headers, the edge guard's 401/403/415, and the schemas no route returns
as a model (``Problem``, ``FrameMessage``).
"""

from __future__ import annotations

import copy
from typing import Any

from ..scene.model import Effect, Scene
from .models import FRAME_HEADERS, STATE_HEADERS, FrameMessage
from .problems import PROBLEM_KINDS, Problem

REF = "#/components/schemas/{model}"
PROBLEM_REF = {"$ref": "#/components/schemas/Problem"}
PROBLEM_CONTENT = {"application/problem+json": {"schema": PROBLEM_REF},
                   "application/problem+msgpack": {"schema": PROBLEM_REF}}
WRITES = ("post", "put", "patch")
# status -> what it means on this API (descriptions of the documented problem answers)
STATUS_TEXT = {
    400: "malformed body or parameter",
    401: "bearer token missing or wrong (when the server has one)",
    403: "Host or Origin not allowed",
    404: "no such resource",
    406: "Accept names no format this route answers in",
    409: "conflict with the current state",
    413: "body, string, array or nesting over a limit",
    415: "a write without a JSON or msgpack Content-Type",
    422: "a field or query parameter of the wrong type, out of range, NaN/Inf or unknown",
    500: "internal error (details in the server log)",
    503: "render process unavailable (retry after the Retry-After seconds)",
}


def _add_models(components: dict, *models) -> None:
    for model in models:
        schema = model.model_json_schema(ref_template=REF)
        for name, sub in schema.pop("$defs", {}).items():
            components.setdefault(name, sub)
        components[model.__name__] = schema


def _partial(schema: dict, components: dict, deep: bool) -> dict:
    """An object schema with nothing required and no defaults (an omitted field keeps its current value).

    ``deep``: nested objects (reached through properties, not through arrays: lists replace whole) become
    partial too, as ``<Name>Patch`` components: a state patch merges maps key by key.
    """
    out = copy.deepcopy(schema)
    out.pop("required", None)
    for prop in out.get("properties", {}).values():
        prop.pop("default", None)
        if not deep:
            continue
        for holder in [prop, *prop.get("anyOf", [])]:
            ref = holder.get("$ref", "")
            name = ref.rsplit("/", 1)[-1]
            target = components.get(name, {})
            if ref and target.get("type") == "object" and "properties" in target:
                patch_name = f"{name}Patch"
                if patch_name not in components:
                    components[patch_name] = {}  # placeholder against cycles
                    components[patch_name] = _partial(target, components, deep)
                    components[patch_name]["title"] = patch_name
                holder["$ref"] = REF.format(model=patch_name)
    return out


def _problem_responses(operation: dict, path: str, method: str) -> None:
    responses = operation.setdefault("responses", {})
    codes = {401, 403, 500}
    if operation.get("parameters"):
        codes.add(422)
    if method in WRITES or "requestBody" in operation:
        codes |= {400, 413, 415, 422}
    if path.startswith(("/v1/state", "/v1/effects")):
        codes.add(406)
    if path.startswith(("/v1/effects/{",)):
        codes.add(404)
    if path in ("/v1/frame", "/v1/render"):
        codes.add(503)
    for code in sorted(codes):
        responses.setdefault(str(code), {"description": STATUS_TEXT[code]})
    for code, response in responses.items():
        if code == "default" or int(code) >= 400:
            response["content"] = copy.deepcopy(PROBLEM_CONTENT)
            response.setdefault("description", STATUS_TEXT.get(int(code), "problem"))
            if code == "405":
                response.setdefault("headers", {})["Allow"] = {"schema": {"type": "string"}}
    responses["default"] = {"description": "any other error, as a problem document",
                            "content": copy.deepcopy(PROBLEM_CONTENT)}
    for code in ("401",):
        responses[code]["headers"] = {"WWW-Authenticate": {"schema": {"type": "string"}}}
    if "503" in responses:
        responses["503"]["headers"] = {"Retry-After": {"schema": {"type": "integer"}}}


def _document_headers(operation: dict, path: str) -> None:
    ok = operation.get("responses", {}).get("200")
    if ok is None:
        return
    if any(media.startswith("image/") for media in ok.get("content", {})):
        ok["headers"] = {**ok.get("headers", {}), **copy.deepcopy(FRAME_HEADERS)}
    elif path == "/v1/state":
        ok["headers"] = {**ok.get("headers", {}), **copy.deepcopy(STATE_HEADERS)}


def _uniform_tuples(node: Any) -> None:
    """``prefixItems`` whose items are all alike (Vec3) -> ``items``: the same constraint, readable by tools
    that only know OpenAPI 3.0's ``items`` (Swagger UI's form, schemathesis' response checks)."""
    if isinstance(node, dict):
        prefix = node.get("prefixItems")
        if isinstance(prefix, list) and prefix and all(item == prefix[0] for item in prefix):
            node["items"] = node.pop("prefixItems")[0]
        for value in node.values():
            _uniform_tuples(value)
    elif isinstance(node, list):
        for value in node:
            _uniform_tuples(value)


def complete_schema(schema: dict[str, Any]) -> dict[str, Any]:
    components = schema.setdefault("components", {}).setdefault("schemas", {})
    _add_models(components, Problem, FrameMessage, Scene, Effect)
    components["ScenePatch"] = _partial(components["Scene"], components, deep=True)
    components["ScenePatch"]["title"] = "ScenePatch"
    components["ScenePatch"]["description"] = (
        "A partial Scene: maps merge key by key, lists and values replace. Validated whole: the result "
        "must be a valid Scene, else nothing changes.")
    components["EffectPatch"] = _partial(components["Effect"], components, deep=False)
    components["EffectPatch"]["title"] = "EffectPatch"
    components["EffectPatch"]["properties"].pop("id", None)  # the id is the path's; it cannot change
    for unused in ("HTTPValidationError", "ValidationError"):
        components.pop(unused, None)
    for path, item in schema.get("paths", {}).items():
        for method, operation in item.items():
            if method not in ("get", "put", "post", "patch", "delete", "head", "options"):
                continue
            _problem_responses(operation, path, method)
            _document_headers(operation, path)
    _uniform_tuples(schema)
    schema["x-problem-kinds"] = {k: {"status": s, "title": t} for k, (s, t) in PROBLEM_KINDS.items()}
    schema.setdefault("components", {})["securitySchemes"] = {
        "bearer": {"type": "http", "scheme": "bearer",
                   "description": "required when the server has a token (always when bound beyond loopback)"},
    }
    schema["security"] = [{}, {"bearer": []}]  # optional: servers on loopback may run without a token
    return schema
