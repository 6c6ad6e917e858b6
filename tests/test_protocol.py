"""Protocol v1 through a real uvicorn server on loopback (real render process, 64x36 frames).

Every route, msgpack and JSON round trips, and the problem errors; after every rejected message the
state (and its revision) must equal the state before.
"""

from __future__ import annotations

import io
import json
import shutil
import subprocess

import httpx
import msgpack
import pytest
from PIL import Image

from igserver.client import iter_multipart_jpegs
from igserver.protocol.runtime import ServerSettings
from igserver.protocol.testing import LoopbackServer
from igserver.scene import Scene

W, H = 64, 36
MSGPACK = "application/vnd.msgpack"
JSON_CT = "application/json"


def small_scene(**extra) -> Scene:
    # the gradient sky needs no precomputed tables: the render process is ready in ~1 s
    tree = {"camera": {"width": W, "height": H}, "atmosphere": {"model": "gradient"}}
    tree.update(extra)
    return Scene.model_validate(tree)


@pytest.fixture(scope="module")
def server():
    with LoopbackServer(small_scene(), ServerSettings(keepalive_s=0.25)) as srv:
        # a frozen IG clock: these tests compare states and count frames, which a running sim_time changes
        httpx.patch(srv.url + "/v1/clock", json={"paused": True}).raise_for_status()
        yield srv


@pytest.fixture()
def http(server):
    with httpx.Client(base_url=server.url, timeout=30) as client:
        yield client


def pack(value) -> bytes:
    return msgpack.packb(value, use_bin_type=True)


def unpack(data: bytes):
    return msgpack.unpackb(data, raw=False)


def snapshot(http) -> tuple[dict, str]:
    response = http.get("/v1/state", headers={"Accept": JSON_CT})
    return response.json(), response.headers["x-ig-revision"]


# --------------------------------------------------------------------------- health, readiness, docs

def test_health_and_ready(http):
    assert http.get("/v1/health").json()["status"] == "ok"
    ready = http.get("/v1/ready")
    assert ready.status_code == 200
    body = ready.json()
    assert body["ready"] is True and body["renderer"] and body["gl_version"] and body["pid"]


def test_openapi_documents_both_formats(http):
    schema = http.get("/openapi.json").json()
    for path in ("/v1/state", "/v1/frame", "/v1/render", "/v1/stream.mjpg", "/v1/effects", "/v1/effects/{effect_id}"):
        assert path in schema["paths"], path
    put = schema["paths"]["/v1/state"]["put"]["requestBody"]["content"]
    assert set(put) == {JSON_CT, MSGPACK}
    assert {"Scene", "Problem", "FrameMessage"} <= set(schema["components"]["schemas"])


def test_viewer_page(http):
    page = http.get("/")
    assert page.status_code == 200 and "text/html" in page.headers["content-type"]
    assert "/v1/stream.mjpg" in page.text and "/v1/effects" in page.text


# --------------------------------------------------------------------------- state round trips

@pytest.mark.parametrize("content_type", [MSGPACK, "application/x-msgpack", "application/msgpack"])
def test_put_msgpack_round_trip(http, content_type):
    scene = small_scene(host_frame=41, camera={"width": W, "height": H, "heading": 33.5, "position": [1.0, 2.0, 3.25]})
    tree = scene.model_dump(mode="json")
    response = http.put("/v1/state", content=pack(tree), headers={"Content-Type": content_type})
    assert response.status_code == 200
    assert response.headers["content-type"] == MSGPACK  # answered in the caller's format
    assert unpack(response.content) == tree
    got = http.get("/v1/state", headers={"Accept": MSGPACK})
    assert got.headers["content-type"] == MSGPACK
    assert Scene.model_validate(unpack(got.content)) == scene


def test_json_round_trip_and_accept_wins(http):
    scene = small_scene(host_frame=42, weather={"wind_speed": 12.5})
    response = http.put("/v1/state", json=scene.model_dump(mode="json"))
    assert response.headers["content-type"] == JSON_CT
    assert Scene.model_validate(response.json()) == scene
    # JSON in, msgpack asked for: Accept decides
    response = http.patch("/v1/state", json={"host_frame": 43}, headers={"Accept": MSGPACK})
    assert response.headers["content-type"] == MSGPACK and unpack(response.content)["host_frame"] == 43


def test_patch_merges_and_prefer_minimal(http):
    http.put("/v1/state", json=small_scene(weather={"wind_speed": 7.0}).model_dump(mode="json"))
    before, revision = snapshot(http)
    response = http.patch("/v1/state", content=pack({"host_frame": 44, "camera": {"pitch": -5.0}}),
                          headers={"Content-Type": MSGPACK, "Prefer": "return=minimal"})
    assert unpack(response.content) == {"revision": int(revision) + 1, "host_frame": 44}
    after, _ = snapshot(http)
    assert after["camera"]["pitch"] == -5.0
    assert after["camera"]["heading"] == before["camera"]["heading"]
    assert after["weather"] == before["weather"]


# --------------------------------------------------------------------------- problem errors

NAN_MSGPACK = pack({"camera": {"pitch": float("nan")}})
INF_MSGPACK = pack({"camera": {"position": [0.0, float("inf"), 1.0]}})
EXT_MSGPACK = msgpack.packb({"camera": msgpack.ExtType(5, b"xx")})
DEEP = pack(json.loads("[" * 40 + "]" * 40))

BAD_MESSAGES = [
    # (id, content type, body, status, kind, pointer of the offending field or None)
    ("malformed-msgpack", MSGPACK, b"\xc1\x00\x01", 400, "malformed", None),
    ("truncated-msgpack", MSGPACK, pack({"camera": {"pitch": 1.0}})[:-3], 400, "malformed", None),
    ("trailing-bytes", MSGPACK, pack({}) + b"\x01", 400, "malformed", None),
    ("malformed-json", JSON_CT, b'{"camera": ', 400, "malformed", None),
    ("wrong-type", MSGPACK, pack({"camera": {"pitch": "up"}}), 422, "validation", "#/camera/pitch"),
    ("wrong-type-json", JSON_CT, b'{"weather": {"wind_speed": [1]}}', 422, "validation", "#/weather/wind_speed"),
    ("nan-msgpack", MSGPACK, NAN_MSGPACK, 422, "non_finite", "#/camera/pitch"),
    ("inf-msgpack", MSGPACK, INF_MSGPACK, 422, "non_finite", "#/camera/position/1"),
    ("nan-json-literal", JSON_CT, b'{"camera": {"fov_y": NaN}}', 422, "non_finite", "#/camera/fov_y"),
    ("inf-json-literal", JSON_CT, b'{"time": {"sim_time": -Infinity}}', 422, "non_finite", "#/time/sim_time"),
    ("out-of-range", MSGPACK, pack({"camera": {"pitch": 91.0}}), 422, "validation", "#/camera/pitch"),
    ("negative-host-frame", MSGPACK, pack({"host_frame": -1}), 422, "validation", "#/host_frame"),
    ("unknown-field", MSGPACK, pack({"camera": {"zoom": 2.0}}), 422, "validation", "#/camera/zoom"),
    ("unknown-top-level", JSON_CT, b'{"colour": 1}', 422, "validation", "#/colour"),
    ("effect-out-of-range", MSGPACK, pack({"effects": [{"id": "f1", "diameter": -1.0}]}), 422, "validation",
     "#/effects/0/diameter"),
    ("oversized-body", MSGPACK, pack({"entities": [{"id": "e" * 60}] * 20000}), 413, "limits", None),
    ("long-string", MSGPACK, pack({"effects": [{"id": "x", "profile": "p" * 5000}]}), 413, "limits", None),
    ("long-array", MSGPACK, pack({"lights": [0] * 5000}), 413, "limits", None),
    ("deep-nesting", MSGPACK, DEEP, 413, "limits", None),
    ("ext-type", MSGPACK, EXT_MSGPACK, 400, "malformed", None),
    ("binary-value", MSGPACK, pack({"effects": [{"id": b"f1"}]}), 422, "validation", "#/effects/0/id"),
    ("not-a-map", MSGPACK, pack([1, 2, 3]), 422, "validation", "#"),
    ("empty-body", MSGPACK, b"", 400, "malformed", None),
    ("text-plain", "text/plain", b"camera.pitch=5", 415, "unsupported_media_type", None),
    ("integer-map-key", MSGPACK, msgpack.packb({1: 2}, strict_types=False), 400, "malformed", None),
]


@pytest.mark.parametrize("case", BAD_MESSAGES, ids=[c[0] for c in BAD_MESSAGES])
@pytest.mark.parametrize("method", ["PATCH", "PUT"])
def test_rejected_message_changes_nothing(http, case, method):
    _, content_type, body, status, kind, pointer = case
    before, revision = snapshot(http)
    response = http.request(method, "/v1/state", content=body, headers={"Content-Type": content_type})
    assert response.status_code == status, response.text
    if "msgpack" in content_type:
        assert response.headers["content-type"] == "application/problem+msgpack"
        problem = unpack(response.content)
    else:
        assert response.headers["content-type"] == "application/problem+json"
        problem = response.json()
    assert problem["status"] == status and problem["kind"] == kind
    assert problem["type"].endswith("/" + kind) and problem["title"] and problem["instance"] == "/v1/state"
    if pointer is not None and not (method == "PUT" and kind == "validation" and pointer == "#"):
        assert pointer in [e["pointer"] for e in problem["errors"]], problem
    after, revision_after = snapshot(http)
    assert after == before and revision_after == revision


def test_oversized_content_length_refused_before_reading(server, http):
    before, revision = snapshot(http)
    limit = server.runtime.settings.limits.max_body_bytes
    response = http.patch("/v1/state", content=b"\x80" * (limit + 1), headers={"Content-Type": MSGPACK})
    assert response.status_code == 413
    assert snapshot(http) == (before, revision)


def test_problem_counters_in_metrics(http):
    http.patch("/v1/state", json={"host_frame": 77})
    assert http.get("/v1/frame").status_code == 200
    http.patch("/v1/state", content=NAN_MSGPACK, headers={"Content-Type": MSGPACK})
    text = http.get("/metrics").text
    counts = {line.split(" ")[0]: float(line.split(" ")[1]) for line in text.splitlines() if line and line[0] != "#"}
    assert counts['igserver_protocol_errors_total{kind="non_finite"}'] >= 1
    for name in ("igserver_frames_rendered_total", "igserver_render_process_restarts", "igserver_frame_render_seconds_count",
                 "igserver_state_updates_total{method=\"patch\"}"):
        assert name in counts, name
    assert any(k.startswith('igserver_pass_seconds_count{pass="') for k in counts)


def test_unknown_route_and_method_are_problems(http):
    response = http.get("/v1/nothing")
    assert response.status_code == 404 and response.headers["content-type"] == "application/problem+json"
    assert http.delete("/v1/state").status_code == 405
    assert http.get("/v1/problems/non_finite").json()["status"] == 422


# --------------------------------------------------------------------------- frames

def test_frame_formats_and_headers(http):
    http.patch("/v1/state", json={"host_frame": 500})
    jpeg = http.get("/v1/frame")
    assert jpeg.headers["content-type"] == "image/jpeg"
    assert jpeg.headers["x-ig-host-frame"] == "500" and int(jpeg.headers["x-ig-frame"]) > 0
    assert float(jpeg.headers["x-ig-render-ms"]) > 0
    assert Image.open(io.BytesIO(jpeg.content)).size == (W, H)
    png = http.get("/v1/frame", params={"format": "png"})
    assert Image.open(io.BytesIO(png.content)).mode == "RGBA"
    raw = http.get("/v1/frame", params={"format": "raw"})
    assert raw.headers["content-type"] == "application/octet-stream" and len(raw.content) == W * H * 4
    bad = http.get("/v1/frame", params={"quality": 0})
    assert bad.status_code == 422 and bad.json()["errors"][0]["pointer"] == "#/query/quality"
    assert http.get("/v1/frame", params={"format": "gif"}).status_code == 422


def test_render_returns_frame_of_exactly_that_state(http):
    http.put("/v1/state", json=small_scene().model_dump(mode="json"))
    up = http.post("/v1/render", params={"format": "raw"}, json={"host_frame": 601, "camera": {"pitch": 60.0}})
    down = http.post("/v1/render", params={"format": "raw"}, json={"host_frame": 602, "camera": {"pitch": -60.0}})
    assert up.headers["x-ig-host-frame"] == "601" and down.headers["x-ig-host-frame"] == "602"
    assert int(down.headers["x-ig-frame"]) > int(up.headers["x-ig-frame"])
    assert up.content != down.content  # sky above, ground below
    assert snapshot(http)[0]["camera"]["pitch"] == -60.0  # and it was accepted
    # msgpack callers get the frame map, as on the WebSocket
    message = unpack(http.post("/v1/render", content=pack({"host_frame": 603}),
                               headers={"Content-Type": MSGPACK, "Accept": MSGPACK}).content)
    assert message["host_frame"] == 603 and message["format"] == "jpeg" and message["width"] == W
    assert Image.open(io.BytesIO(message["data"])).size == (W, H)
    rejected = http.post("/v1/render", content=NAN_MSGPACK, headers={"Content-Type": MSGPACK})
    assert rejected.status_code == 422 and snapshot(http)[0]["host_frame"] == 603


# --------------------------------------------------------------------------- effects

def test_effects_lifecycle(http):
    http.put("/v1/state", json=small_scene(time={"sim_time": 10.0}).model_dump(mode="json"))
    created = http.post("/v1/effects", json={"id": "fire-1", "type": "fire", "position": [0, 30, 0], "diameter": 3})
    assert created.status_code == 201 and created.headers["location"] == "/v1/effects/fire-1"
    assert created.json()["changed_at"] == 10.0 and created.json()["active"] is True
    assert http.post("/v1/effects", json={"id": "fire-1"}).status_code == 409
    assert [e["id"] for e in http.get("/v1/effects").json()] == ["fire-1"]
    assert unpack(http.get("/v1/effects/fire-1", headers={"Accept": MSGPACK}).content)["diameter"] == 3.0

    http.patch("/v1/state", json={"time": {"sim_time": 25.0}})
    grown = http.patch("/v1/effects/fire-1", json={"intensity": 2.0})
    assert grown.json()["intensity"] == 2.0 and grown.json()["changed_at"] == 10.0  # not a switch: no new fade
    out = http.delete("/v1/effects/fire-1")
    assert out.status_code == 202 and out.json()["active"] is False and out.json()["changed_at"] == 25.0
    again = http.patch("/v1/effects/fire-1", json={"active": True})
    assert again.json()["active"] is True and again.json()["changed_at"] == 25.0

    before, revision = snapshot(http)
    bad = http.patch("/v1/effects/fire-1", json={"diameter": 1e9})
    assert bad.status_code == 422 and bad.json()["errors"][0]["pointer"] == "#/diameter"
    bad = http.post("/v1/effects", json={"id": "bad id!"})
    assert bad.status_code == 422 and bad.json()["errors"][0]["pointer"] == "#/id"
    assert http.patch("/v1/effects/fire-1", json={"id": "other"}).status_code == 422
    assert snapshot(http) == (before, revision)

    assert http.delete("/v1/effects/fire-1", params={"immediate": True}).status_code == 204
    assert http.get("/v1/effects/fire-1").status_code == 404
    assert http.get("/v1/effects").json() == []


# --------------------------------------------------------------------------- MJPEG

def test_mjpeg_stream_decodes_with_pillow(http):
    http.patch("/v1/state", json={"host_frame": 700})
    with http.stream("GET", "/v1/stream.mjpg", params={"frames": 3}) as response:
        assert response.headers["content-type"].startswith("multipart/x-mixed-replace; boundary=")
        jpegs = list(iter_multipart_jpegs(response.iter_bytes()))
    assert len(jpegs) == 3
    for data in jpegs:
        image = Image.open(io.BytesIO(data))
        assert image.format == "JPEG" and image.size == (W, H)


@pytest.mark.skipif(shutil.which("ffmpeg") is None, reason="ffmpeg not installed (the recording recipe of docs/protocol.md)")
def test_mjpeg_stream_read_by_ffmpeg(server, tmp_path):
    """A tool nobody here wrote demuxes and decodes the stream."""
    result = subprocess.run(
        ["ffmpeg", "-hide_banner", "-loglevel", "error", "-f", "mpjpeg", "-i",
         f"{server.url}/v1/stream.mjpg?frames=2", "-f", "image2", str(tmp_path / "f%02d.png")],
        capture_output=True, timeout=60,
    )
    assert result.returncode == 0, result.stderr.decode()
    frames = sorted(tmp_path.glob("f*.png"))
    assert len(frames) == 2 and Image.open(frames[0]).size == (W, H)


# --------------------------------------------------------------------------- mixed valid + invalid

# Each message has valid sections beside one invalid one: the valid parts must not be applied either
# (a rejected message changes nothing, and the revision does not move). Guards against a store that
# validates section by section and keeps what passed.
MIXED = [
    ("bad-last-section", {"camera": {"pitch": 10.0}, "weather": {"wind_speed": -5.0}}, "validation",
     "#/weather/wind_speed"),
    ("bad-first-section", {"atmosphere": {"visibility": 1.0}, "camera": {"heading": 77.0}}, "validation",
     "#/atmosphere/visibility"),
    ("bad-field-beside-good-one", {"camera": {"pitch": 10.0, "zoom": 2.0}}, "validation", "#/camera/zoom"),
    ("good-effect-bad-light", {"effects": [{"id": "mixed-fire"}], "lights": [{"id": "l", "intensity": -1.0}]},
     "validation", "#/lights/0/intensity"),
    ("good-host-frame-non-finite", {"host_frame": 123456, "time": {"sim_time": float("nan")}}, "non_finite",
     "#/time/sim_time"),
]


@pytest.mark.parametrize("case", MIXED, ids=[c[0] for c in MIXED])
@pytest.mark.parametrize("route", ["PATCH /v1/state", "PUT /v1/state", "POST /v1/render",
                                   "POST /v1/render?replace=true"])
def test_mixed_valid_and_invalid_message_changes_nothing(http, case, route):
    _, message, kind, pointer = case
    method, path = route.split(" ")
    http.put("/v1/state", json=small_scene().model_dump(mode="json"))  # the valid sections would change it
    before, revision = snapshot(http)
    if method == "PUT" or "replace" in path:
        message = {**before, **message}  # a whole valid state with the mixed sections merged over it
    response = http.request(method, path, content=pack(message), headers={"Content-Type": MSGPACK})
    assert response.status_code == 422, response.content
    problem = unpack(response.content)
    assert problem["kind"] == kind and pointer in [e["pointer"] for e in problem["errors"]], problem
    assert snapshot(http) == (before, revision)


def test_mixed_effect_patch_changes_nothing(http):
    http.put("/v1/state", json=small_scene(effects=[{"id": "fx", "diameter": 2.0}]).model_dump(mode="json"))
    before, revision = snapshot(http)
    response = http.patch("/v1/effects/fx", json={"intensity": 2.0, "diameter": -1.0})
    assert response.status_code == 422 and response.json()["errors"][0]["pointer"] == "#/diameter"
    assert snapshot(http) == (before, revision)
    assert http.get("/v1/effects/fx").json()["intensity"] == 1.0
