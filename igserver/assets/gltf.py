"""Cheap, bounded checking of a glTF 2.0 model before anything loads it.

The protocol calls ``check_model(name)`` whenever an entity names a model, so a bad file
(truncated, wrong version, a missing or escaping buffer, absurd sizes, a 30k x 30k texture) is a
clear validation error at the edge and never reaches the render process. The check reads the
JSON header and the image headers only (no vertex data is decoded), bounds every count and byte
range it meets, and caches its answer by file identity (path, size, mtime, inode), so a host that
sends the same entity 60 times a second pays one ``stat`` per message.

Everything here is pure Python (no GL, no trimesh): it runs in the server process, where the scene
model checks every entity's model, and in the render process, which loads what it passed.
"""

from __future__ import annotations

import base64
import io
import json
import os
import struct
import threading
from dataclasses import dataclass
from pathlib import Path

from . import AssetError, check_name, resolve_asset

MODEL_SUFFIXES = (".glb", ".gltf")
BUILTIN_MODELS = ("box",)

# Limits. They bound what one model may cost the render process (memory, upload, draw time);
# real simulator models (a 40 m patrol boat, a pier) sit far below every one of them.
MAX_MODEL_BYTES = 64 * 2**20        # whole .glb / all buffers of a .gltf
MAX_JSON_BYTES = 8 * 2**20
MAX_VERTICES = 2_000_000            # summed over all primitives' POSITION accessors
MAX_INDICES = 6_000_000
MAX_NODES = 4096
MAX_PRIMITIVES = 4096
MAX_TEXTURE_SIDE = 8192             # px; a 30k x 30k texture would be 3.6 GB of RGBA
MAX_TEXTURE_PIXELS = 64 * 2**20     # summed over all images
SUPPORTED_EXTENSIONS: frozenset[str] = frozenset()  # required extensions we can render

_COMPONENT_BYTES = {5120: 1, 5121: 1, 5122: 2, 5123: 2, 5125: 4, 5126: 4}
_TYPE_COUNT = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
_GLB_MAGIC = b"glTF"
_CHUNK_JSON = 0x4E4F534A
_CHUNK_BIN = 0x004E4942


class ModelError(AssetError):
    """A model file that cannot be served; the message names the model, never a server path."""


@dataclass(frozen=True)
class ModelInfo:
    name: str
    node_names: frozenset[str]
    vertices: int
    textures: int
    file_bytes: int
    blended: bool = False  # a material with alphaMode BLEND (drawn by the late blended-surfaces pass)


_cache: dict[tuple, ModelInfo] = {}
_cache_lock = threading.Lock()


def model_path(name: str) -> Path:
    return resolve_asset("models", name, MODEL_SUFFIXES)


def check_model(name: str) -> ModelInfo:
    """Validate model asset ``name`` (cached by file identity); raises ModelError / AssetError."""
    if name in BUILTIN_MODELS:
        return ModelInfo(name, frozenset(), 36, 0, 0)
    path = model_path(name)
    if path.suffix.lower() not in MODEL_SUFFIXES:
        raise ModelError(f"model {name!r} is not a .glb or .gltf file")
    st = os.stat(path)
    key = (str(path), st.st_size, st.st_mtime_ns, st.st_ino)
    with _cache_lock:
        hit = _cache.get(key)
    if hit is not None:
        return hit
    info = _check_file(name, path, st.st_size)
    with _cache_lock:
        if len(_cache) > 256:
            _cache.clear()
        _cache[key] = info
    return info


def _fail(name: str, what: str) -> ModelError:
    return ModelError(f"model {name!r}: {what}")


def _check_file(name: str, path: Path, size: int) -> ModelInfo:
    if size > MAX_MODEL_BYTES:
        raise _fail(name, f"file larger than {MAX_MODEL_BYTES // 2**20} MiB")
    with open(path, "rb") as f:
        head = f.read(12)
        if path.suffix.lower() == ".glb" or head[:4] == _GLB_MAGIC:
            doc, bin_chunk = _read_glb(name, f, head, size)
        else:
            if size > MAX_JSON_BYTES:
                raise _fail(name, f"JSON larger than {MAX_JSON_BYTES // 2**20} MiB")
            f.seek(0)
            doc, bin_chunk = _parse_json(name, f.read(MAX_JSON_BYTES + 1)), None
    return _check_document(name, path, doc, bin_chunk, size)


def _parse_json(name: str, raw: bytes) -> dict:
    try:
        doc = json.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
        raise _fail(name, f"not valid glTF JSON ({type(exc).__name__})") from None
    if not isinstance(doc, dict):
        raise _fail(name, "glTF JSON is not an object")
    return doc


def _read_glb(name: str, f, head: bytes, size: int) -> tuple[dict, bytes | None]:
    if len(head) < 12 or head[:4] != _GLB_MAGIC:
        raise _fail(name, "not a binary glTF (bad magic)")
    version, length = struct.unpack_from("<II", head, 4)
    if version != 2:
        raise _fail(name, f"binary glTF version {version}, only version 2 is supported")
    if length != size:
        raise _fail(name, f"truncated or padded: header says {length} bytes, file has {size}")
    chunk = f.read(8)
    if len(chunk) < 8:
        raise _fail(name, "truncated (no JSON chunk)")
    json_len, json_type = struct.unpack("<II", chunk)
    if json_type != _CHUNK_JSON or json_len > MAX_JSON_BYTES or 20 + json_len > size:
        raise _fail(name, "bad JSON chunk (type, or length beyond the file or the limit)")
    doc = _parse_json(name, f.read(json_len))
    bin_chunk = None
    chunk = f.read(8)
    if len(chunk) == 8:
        bin_len, bin_type = struct.unpack("<II", chunk)
        if bin_type == _CHUNK_BIN:
            if 28 + json_len + bin_len > size:
                raise _fail(name, "truncated binary chunk")
            bin_chunk = f.read(bin_len)
    return doc, bin_chunk


def _items(doc: dict, key: str, name: str, limit: int = 100_000) -> list:
    value = doc.get(key, [])
    if not isinstance(value, list) or len(value) > limit:
        raise _fail(name, f"'{key}' must be a list of at most {limit} items")
    if not all(isinstance(v, dict) for v in value):
        raise _fail(name, f"'{key}' entries must be objects")
    return value


def _int(value, name: str, what: str, lo: int = 0, hi: int = 2**40) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        raise _fail(name, f"{what} must be an integer in [{lo}, {hi}]")
    return value


def _external_file(name: str, model: Path, uri: str) -> Path:
    """A .gltf's external buffer/image: a plain file name beside the model, nothing else."""
    if ":" in uri or "/" in uri or "\\" in uri or "%" in uri:
        raise _fail(name, f"external file {uri[:64]!r} must be a plain file name in the models directory")
    try:
        check_name(uri)
    except AssetError:
        raise _fail(name, f"external file {uri[:64]!r} is not a plain name") from None
    folder = model.parent
    try:
        real = (folder / uri).resolve(strict=True)
    except (OSError, RuntimeError):
        raise _fail(name, f"external file {uri!r} is missing") from None
    if real.parent != folder or not real.is_file():
        raise _fail(name, f"external file {uri!r} lies outside the models directory")
    return real


def _data_uri(name: str, uri: str) -> bytes:
    try:
        return base64.b64decode(uri.split(",", 1)[1], validate=True)
    except (IndexError, ValueError):
        raise _fail(name, "bad base64 data URI") from None


def _check_document(name: str, path: Path, doc: dict, bin_chunk: bytes | None, file_size: int) -> ModelInfo:
    asset = doc.get("asset")
    version = asset.get("version") if isinstance(asset, dict) else None
    if not isinstance(version, str) or not version.startswith("2."):
        raise _fail(name, f"glTF asset.version {version!r}, only 2.x is supported")
    required = doc.get("extensionsRequired", [])
    if not isinstance(required, list) or set(map(str, required)) - SUPPORTED_EXTENSIONS:
        raise _fail(name, f"requires unsupported extensions {sorted(map(str, required))[:8]}")

    # Buffers: where every byte range must fall.
    buffers = _items(doc, "buffers", name, 1024)
    buffer_bytes: list[int] = []
    total = 0
    for i, buf in enumerate(buffers):
        length = _int(buf.get("byteLength"), name, f"buffers[{i}].byteLength", 1, MAX_MODEL_BYTES)
        uri = buf.get("uri")
        if uri is None:
            if i != 0 or bin_chunk is None:
                raise _fail(name, f"buffers[{i}] has no uri and no GLB binary chunk")
            if len(bin_chunk) < length:
                raise _fail(name, f"buffers[{i}] is truncated ({len(bin_chunk)} of {length} bytes)")
        elif not isinstance(uri, str):
            raise _fail(name, f"buffers[{i}].uri must be a string")
        elif uri.startswith("data:"):
            if len(uri) > MAX_MODEL_BYTES * 4 // 3 + 64 or len(_data_uri(name, uri)) < length:
                raise _fail(name, f"buffers[{i}] data URI is shorter than its byteLength or too large")
        else:
            if os.stat(_external_file(name, path, uri)).st_size < length:
                raise _fail(name, f"buffers[{i}] file {uri!r} is truncated")
        total += length
        buffer_bytes.append(length)
    if total > MAX_MODEL_BYTES:
        raise _fail(name, f"buffers total more than {MAX_MODEL_BYTES // 2**20} MiB")

    views = _items(doc, "bufferViews", name)
    for i, view in enumerate(views):
        b = _int(view.get("buffer"), name, f"bufferViews[{i}].buffer", 0, len(buffers) - 1)
        offset = _int(view.get("byteOffset", 0), name, f"bufferViews[{i}].byteOffset")
        length = _int(view.get("byteLength"), name, f"bufferViews[{i}].byteLength", 1)
        if offset + length > buffer_bytes[b]:
            raise _fail(name, f"bufferViews[{i}] reaches past the end of buffers[{b}]")
        if "byteStride" in view:
            _int(view["byteStride"], name, f"bufferViews[{i}].byteStride", 4, 252)

    accessors = _items(doc, "accessors", name)
    counts: list[int] = []
    for i, acc in enumerate(accessors):
        comp = acc.get("componentType")
        if comp not in _COMPONENT_BYTES or acc.get("type") not in _TYPE_COUNT:
            raise _fail(name, f"accessors[{i}] has a bad componentType or type")
        count = _int(acc.get("count"), name, f"accessors[{i}].count", 1, MAX_INDICES)
        counts.append(count)
        if "sparse" in acc:
            raise _fail(name, f"accessors[{i}] is sparse (not supported)")
        if "bufferView" not in acc:
            continue  # all zeros by the spec
        v = _int(acc["bufferView"], name, f"accessors[{i}].bufferView", 0, len(views) - 1)
        element = _COMPONENT_BYTES[comp] * _TYPE_COUNT[acc["type"]]
        stride = views[v].get("byteStride", element)
        end = _int(acc.get("byteOffset", 0), name, f"accessors[{i}].byteOffset") + stride * (count - 1) + element
        if end > views[v]["byteLength"]:
            raise _fail(name, f"accessors[{i}] reaches past the end of bufferViews[{v}]")

    vertices = indices = primitives = 0
    for i, mesh in enumerate(_items(doc, "meshes", name)):
        prims = mesh.get("primitives")
        if not isinstance(prims, list) or not prims:
            raise _fail(name, f"meshes[{i}] has no primitives")
        for j, prim in enumerate(prims):
            primitives += 1
            attrs = prim.get("attributes") if isinstance(prim, dict) else None
            if not isinstance(attrs, dict) or "POSITION" not in attrs:
                raise _fail(name, f"meshes[{i}].primitives[{j}] has no POSITION")
            for attr, index in attrs.items():
                _int(index, name, f"meshes[{i}].primitives[{j}].attributes.{attr}", 0, len(accessors) - 1)
            vertices += counts[attrs["POSITION"]]
            if "indices" in prim:
                indices += counts[_int(prim["indices"], name, f"meshes[{i}].primitives[{j}].indices",
                                       0, len(accessors) - 1)]
    if primitives > MAX_PRIMITIVES or vertices > MAX_VERTICES or indices > MAX_INDICES:
        raise _fail(name, f"too much geometry ({primitives} primitives, {vertices} vertices, {indices} indices;"
                          f" limits {MAX_PRIMITIVES}, {MAX_VERTICES}, {MAX_INDICES})")

    nodes = _items(doc, "nodes", name, MAX_NODES)
    node_names = _check_nodes(name, nodes, doc)
    _check_images(name, path, doc, views, buffers, bin_chunk)
    materials = doc.get("materials", [])
    blended = isinstance(materials, list) and any(
        isinstance(m, dict) and str(m.get("alphaMode", "OPAQUE")).upper() == "BLEND" for m in materials)
    return ModelInfo(name, node_names, vertices, len(doc.get("images", [])), file_size, blended)


def _check_nodes(name: str, nodes: list, doc: dict) -> frozenset[str]:
    parent: dict[int, int] = {}
    names = set()
    for i, node in enumerate(nodes):
        children = node.get("children", [])
        if not isinstance(children, list):
            raise _fail(name, f"nodes[{i}].children must be a list")
        for c in children:
            c = _int(c, name, f"nodes[{i}].children", 0, len(nodes) - 1)
            if c in parent or c == i:
                raise _fail(name, f"nodes[{c}] has two parents or is its own child")
            parent[c] = i
        if "mesh" in node:
            _int(node["mesh"], name, f"nodes[{i}].mesh", 0, max(len(doc.get("meshes", [])) - 1, 0))
        if isinstance(node.get("name"), str):
            names.add(node["name"])
    for i in range(len(nodes)):  # cycles: walking up from any node must end at a root
        seen, j = 0, i
        while j in parent:
            j, seen = parent[j], seen + 1
            if seen > len(nodes):
                raise _fail(name, "node hierarchy has a cycle")
    return frozenset(names)


def _check_images(name: str, path: Path, doc: dict, views: list, buffers: list, bin_chunk) -> int:
    total = 0
    for i, image in enumerate(_items(doc, "images", name, 256)):
        if "bufferView" in image:
            v = _int(image["bufferView"], name, f"images[{i}].bufferView", 0, len(views) - 1)
            view = views[v]
            if view["buffer"] != 0 or bin_chunk is None or buffers[0].get("uri") is not None:
                data = _buffer_bytes(name, path, buffers[view["buffer"]])
            else:
                data = bin_chunk
            offset = view.get("byteOffset", 0)
            raw = data[offset:offset + view["byteLength"]]
        elif isinstance(image.get("uri"), str):
            uri = image["uri"]
            raw = _data_uri(name, uri) if uri.startswith("data:") else _external_file(name, path, uri).read_bytes()
        else:
            raise _fail(name, f"images[{i}] has neither bufferView nor uri")
        width, height = _image_size(name, i, raw)
        if width > MAX_TEXTURE_SIDE or height > MAX_TEXTURE_SIDE:
            raise _fail(name, f"images[{i}] is {width}x{height}, larger than {MAX_TEXTURE_SIDE} px a side")
        total += width * height
        if total > MAX_TEXTURE_PIXELS:
            raise _fail(name, f"textures total more than {MAX_TEXTURE_PIXELS // 2**20} Mpx")
    return total


def _buffer_bytes(name: str, path: Path, buffer: dict) -> bytes:
    uri = buffer.get("uri")
    if not isinstance(uri, str):
        raise _fail(name, "image buffer has no data")
    return _data_uri(name, uri) if uri.startswith("data:") else _external_file(name, path, uri).read_bytes()


def _image_size(name: str, i: int, raw: bytes) -> tuple[int, int]:
    """Width and height from the image header (PNG read directly, others through PIL's lazy open)."""
    from PIL import Image

    if raw[:8] == b"\x89PNG\r\n\x1a\n" and len(raw) >= 24 and raw[12:16] == b"IHDR":
        return struct.unpack(">II", raw[16:24])
    try:
        with Image.open(io.BytesIO(raw)) as img:
            return img.size
    except Image.DecompressionBombError:
        raise _fail(name, f"images[{i}] is larger than {MAX_TEXTURE_SIDE} px a side") from None
    except Exception:  # noqa: BLE001 - PIL raises many kinds for a bad header
        raise _fail(name, f"images[{i}] is not a readable PNG/JPEG") from None
