"""The service's edge, through real servers on loopback: safe defaults (content type, Host,
Origin, bearer token and the viewer's cookie login), settings, offline docs, an OpenAPI document that
matches the wire, strict types, limits, 405 Allow, Prometheus metrics."""

from __future__ import annotations

import json
import re
import socket
from pathlib import Path

import httpx
import msgpack
import pytest
from websockets.exceptions import InvalidStatus
from websockets.sync.client import connect

from igserver.cli import build_parser
from igserver.client import IGClient, IGError
from igserver.cli import main as igserver_main
from igserver.protocol.settings import ServerSettings, settings_table
from igserver.protocol.testing import LoopbackServer
from igserver.scene import Scene
from igserver.scene.files import dumps_scene
from igserver.scene.model import Effect

MSGPACK = "application/vnd.msgpack"
TOKEN = "edge-test-token"
ROOT = Path(__file__).resolve().parents[1]


def small_scene() -> Scene:
    return Scene.model_validate({"camera": {"width": 64, "height": 36}, "atmosphere": {"model": "gradient"}})


@pytest.fixture(scope="module")
def open_server():
    with LoopbackServer(small_scene(), ServerSettings(keepalive_s=0.25)) as srv:
        # a frozen IG clock: these tests compare whole states, which a running sim_time changes
        httpx.patch(srv.url + "/v1/clock", json={"paused": True}).raise_for_status()
        yield srv


@pytest.fixture(scope="module")
def token_server():
    settings = ServerSettings(keepalive_s=0.25, token=TOKEN, allowed_origins=["https://console.example"])
    with LoopbackServer(small_scene(), settings) as srv:
        yield srv


@pytest.fixture
def http(open_server):
    with httpx.Client(base_url=open_server.url, timeout=30) as client:
        yield client


def state(http) -> dict:
    return http.get("/v1/state").json()


# --------------------------------------------------------------------------- item 3: safe by default

@pytest.mark.parametrize("content_type", [None, "text/plain", "application/x-www-form-urlencoded",
                                          "multipart/form-data; boundary=x"])
def test_write_without_json_or_msgpack_content_type_is_415(http, content_type):
    """The CSRF vector: a page can POST these types without a preflight. Refused, nothing changes."""
    before = state(http)
    headers = {"Content-Type": content_type} if content_type else {}
    body = json.dumps({"id": "csrf", "type": "fire"}).encode()
    for method, path in (("POST", "/v1/effects"), ("POST", "/v1/render"), ("PATCH", "/v1/state"),
                         ("PUT", "/v1/state")):
        response = http.request(method, path, content=body, headers=headers)
        assert response.status_code == 415, (method, path, response.text)
        assert response.headers["content-type"] == "application/problem+json"
        assert response.json()["kind"] == "unsupported_media_type"
    assert state(http) == before


def test_foreign_origin_cannot_write_same_origin_can(open_server, http):
    before = state(http)
    evil = http.patch("/v1/state", json={"camera": {"pitch": 33.0}}, headers={"Origin": "http://evil.example"})
    assert evil.status_code == 403 and evil.json()["kind"] == "forbidden"
    cross = http.patch("/v1/state", json={"camera": {"pitch": 33.0}}, headers={"Sec-Fetch-Site": "cross-site"})
    assert cross.status_code == 403
    assert state(http) == before
    # the viewer page: its own origin
    own = http.patch("/v1/state", json={"camera": {"pitch": 3.0}}, headers={"Origin": open_server.url})
    assert own.status_code == 200 and own.json()["camera"]["pitch"] == 3.0
    # reading with a foreign Origin is allowed (the browser's CORS rules keep the answer from the page)
    assert http.get("/v1/state", headers={"Origin": "http://evil.example"}).status_code == 200


def test_websocket_from_foreign_origin_is_refused(open_server):
    ws_url = open_server.url.replace("http", "ws") + "/v1/ws"
    with pytest.raises(InvalidStatus) as info:
        with connect(ws_url, origin="http://evil.example"):
            pass
    assert info.value.response.status_code == 403
    with connect(ws_url, origin=open_server.url) as ws:  # same origin: the viewer
        ws.send(msgpack.packb({"type": "hello", "credits": 1}))
        assert msgpack.unpackb(ws.recv(30))["type"] == "frame"


@pytest.mark.parametrize("host,status", [("evil.example", 403), ("evil.example:8600", 403),
                                         ("localhost", 200), ("[::1]:8600", 200), ("127.0.0.1", 200)])
def test_host_header_allow_list_refuses_dns_rebinding(http, host, status):
    response = http.get("/v1/state", headers={"Host": host})
    assert response.status_code == status, response.text


def test_token_required_and_viewer_login_cookie(token_server):
    url = token_server.url
    with httpx.Client(base_url=url, timeout=30) as anonymous:
        refused = anonymous.get("/v1/state")
        assert refused.status_code == 401 and refused.headers["www-authenticate"].startswith("Bearer")
        assert refused.json()["kind"] == "unauthorized"
        assert anonymous.get("/", headers={"Authorization": "Bearer wrong"}).status_code == 401
        assert anonymous.patch("/v1/state", json={"host_frame": 5}).status_code == 401
        # open without a token: liveness and the documentation
        assert anonymous.get("/v1/health").status_code == 200
        assert anonymous.get("/docs").status_code == 200
        assert anonymous.get("/openapi.json").status_code == 200
    with httpx.Client(base_url=url, timeout=30, headers={"Authorization": f"Bearer {TOKEN}"}) as host:
        assert host.patch("/v1/state", json={"host_frame": 6}).json()["host_frame"] == 6
    with httpx.Client(base_url=url, timeout=30) as browser:
        login = browser.get(f"/?access_token={TOKEN}", follow_redirects=False)
        assert login.status_code == 303 and login.headers["location"] == "/"
        cookie = login.headers["set-cookie"]
        assert "HttpOnly" in cookie and "SameSite=Strict" in cookie
        assert "<html" in browser.get("/").text.lower()  # the cookie now opens the viewer
        ok = browser.patch("/v1/state", json={"host_frame": 7}, headers={"Origin": url})
        assert ok.status_code == 200
        ws_url = url.replace("http", "ws") + "/v1/ws"
        with connect(ws_url, origin=url, additional_headers={"Cookie": f"igserver_token={TOKEN}"}) as ws:
            ws.send(msgpack.packb({"type": "hello", "credits": 1}))
            assert msgpack.unpackb(ws.recv(30))["type"] == "frame"
    with pytest.raises(InvalidStatus) as info:
        with connect(url.replace("http", "ws") + "/v1/ws"):
            pass
    assert info.value.response.status_code == 403  # a refused handshake is answered 403 by uvicorn
    # the Python client and its WebSocket stream carry the token
    with IGClient(url, token=TOKEN) as ig:
        assert ig.patch_state({"host_frame": 9}).host_frame == 9
        with ig.stream(credits=1) as stream:  # the first frame may predate the patch: the newest follows
            assert any(stream.recv().host_frame == 9 for _ in range(20))
    with IGClient(url) as ig, pytest.raises(IGError) as info:
        ig.get_state()
    assert info.value.status == 401
    # a configured origin (a console on another host) may write with the token
    with httpx.Client(base_url=url, timeout=30, headers={"Authorization": f"Bearer {TOKEN}"}) as console:
        assert console.patch("/v1/state", json={"host_frame": 8},
                             headers={"Origin": "https://console.example"}).status_code == 200


def test_health_command_for_container_checks(token_server, monkeypatch, capsys):
    """Docker's HEALTHCHECK: ``igserver health`` reads the same IGSERVER_* settings as the server."""
    monkeypatch.setenv("IGSERVER_PORT", str(token_server.port))
    monkeypatch.setenv("IGSERVER_HOST", "0.0.0.0")  # as in the image: checked through loopback
    monkeypatch.delenv("IGSERVER_TOKEN", raising=False)
    assert igserver_main(["health"]) == 1  # /v1/ready needs the token
    assert igserver_main(["health", "--live"]) == 0
    monkeypatch.setenv("IGSERVER_TOKEN", TOKEN)
    assert igserver_main(["health"]) == 0 and '"ready":true' in capsys.readouterr().out.replace(" ", "")


def test_serve_refuses_non_loopback_without_token(capsys, monkeypatch):
    monkeypatch.delenv("IGSERVER_TOKEN", raising=False)
    assert igserver_main(["serve", "--host", "0.0.0.0", "--port", "0"]) == 2
    err = capsys.readouterr()
    assert "without a token" in err.err and "viewer at" not in err.out


def test_port_in_use_is_reported_before_the_viewer_line(capsys):
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen(1)
        port = busy.getsockname()[1]
        assert igserver_main(["serve", "--scene", "sky_only", "--port", str(port)]) == 2
    out = capsys.readouterr()
    assert f"cannot listen on 127.0.0.1:{port}" in out.err and "viewer at" not in out.out
    assert "Traceback" not in out.err


def test_wrong_scene_name_lists_the_scenes(capsys):
    assert igserver_main(["serve", "--scene", "no_such_scene"]) == 2
    err = capsys.readouterr().err
    assert "no_such_scene" in err and "demo" in err and "sky_only" in err


def test_render_without_egl_is_a_message(tmp_path):
    import os
    import subprocess
    import sys

    env = {**os.environ, "IGSERVER_EGL_DEVICE": "99"}  # no such EGL device: context creation fails
    result = subprocess.run([sys.executable, "-m", "igserver.cli", "render", "--scene", "sky_only", "--out",
                             str(tmp_path / "x.png"), "--width", "64", "--height", "36"],
                            capture_output=True, text=True, timeout=120, env=env)
    assert result.returncode == 1 and "Traceback" not in result.stderr
    assert "EGL" in result.stderr and "install" in result.stderr


# --------------------------------------------------------------------------- item 10: settings, metrics, TOML

def test_toml_writer_round_trips_awkward_strings():
    import tomllib

    text = 'tab\there\nnew line "quoted" back\\slash'
    effect = Effect(id="e1").model_copy(update={"profile": text})  # any string the writer may meet
    scene = small_scene().model_copy(update={"effects": [effect]})
    tree = tomllib.loads(dumps_scene(scene))
    assert tree["effects"][0]["profile"] == text
    # (the model itself refuses such a profile now: profiles are asset names; the writer must still cope)
    tree["effects"][0]["profile"] = None
    assert Scene.model_validate(tree) == scene.model_copy(update={"effects": [effect.model_copy(update={"profile": None})]})


def test_settings_from_flags_then_environment_then_defaults(monkeypatch):
    monkeypatch.setenv("IGSERVER_MAX_FPS", "20")
    monkeypatch.setenv("IGSERVER_JPEG_QUALITY", "50")
    monkeypatch.setenv("IGSERVER_ALLOWED_HOSTS", "ig.lab,ig2.lab")
    monkeypatch.setenv("IGSERVER_LIMITS__MAX_DEPTH", "8")
    args = build_parser().parse_args(["serve", "--max-fps", "30", "--port", "9000"])
    settings = ServerSettings(_cli_settings_source=args.settings_source(parsed_args=args))
    assert settings.max_fps == 30.0 and settings.port == 9000  # flags win
    assert settings.jpeg_quality == 50 and settings.allowed_hosts == ["ig.lab", "ig2.lab"]  # environment
    assert settings.limits.max_depth == 8 and settings.keepalive_s == 1.0  # nested env, default


def test_settings_table_in_the_docs_is_current():
    doc = (ROOT / "docs" / "operations.md").read_text()
    assert settings_table() in doc, "docs/operations.md settings table out of date: paste settings_table()"


def test_metrics_from_prometheus_client_in_seconds(http):
    assert http.get("/v1/frame").status_code == 200
    text = http.get("/metrics").text
    assert "process_resident_memory_bytes" in text  # the process collector
    assert re.search(r'^igserver_frame_render_seconds_bucket\{le="0.005"\} \d', text, re.M)
    assert "igserver_frame_render_ms" not in text
    om = http.get("/metrics", headers={"Accept": "application/openmetrics-text; version=1.0.0"})
    assert om.headers["content-type"].startswith("application/openmetrics-text")
    assert om.text.rstrip().endswith("# EOF")


# --------------------------------------------------------------------------- items 6 and 7: docs and OpenAPI

def test_docs_work_offline(http):
    for page, asset in (("/docs", "swagger-ui-bundle.js"), ("/redoc", "redoc.standalone.js")):
        html = http.get(page).text
        assert "cdn." not in html and "http://" not in html and "https://" not in html, page
        src = re.search(r'src="([^"]*' + re.escape(asset) + ')"', html).group(1)
        script = http.get(src)
        assert script.status_code == 200 and len(script.content) > 100_000  # the real bundle, served locally
    assert http.get(re.search(r'href="([^"]*swagger-ui\.css)"', http.get("/docs").text).group(1)).status_code == 200


def test_openapi_matches_the_wire(http):
    doc = http.get("/openapi.json").json()
    schemas = doc["components"]["schemas"]
    assert "HTTPValidationError" not in schemas and "FrameMessage" in schemas
    for path, item in doc["paths"].items():
        for method, op in item.items():
            for code, response in op["responses"].items():
                if code == "default" or int(code) >= 400:
                    ref = response["content"]["application/problem+json"]["schema"]["$ref"]
                    assert ref.endswith("/Problem"), (path, method, code)
            if method == "delete":
                assert "200" not in op["responses"], path
    # typed patch bodies: the scene model with nothing required
    body = doc["paths"]["/v1/state"]["patch"]["requestBody"]["content"]["application/json"]["schema"]
    assert body["$ref"].endswith("/ScenePatch")
    assert "required" not in schemas["ScenePatch"] and "required" not in schemas["CameraPatch"]
    effect_patch = doc["paths"]["/v1/effects/{effect_id}"]["patch"]["requestBody"]["content"]["application/json"]
    assert effect_patch["schema"]["$ref"].endswith("/EffectPatch") and "required" not in schemas["EffectPatch"]
    frame_headers = doc["paths"]["/v1/frame"]["get"]["responses"]["200"]["headers"]
    assert {"X-IG-Frame", "X-IG-Host-Frame", "X-IG-Width", "X-IG-Height", "X-IG-Render-Ms",
            "X-IG-Encode-Ms"} <= set(frame_headers)
    assert "X-IG-Revision" in doc["paths"]["/v1/state"]["patch"]["responses"]["200"]["headers"]
    assert "/v1/ws-protocol" in doc["info"]["description"] and "/asyncapi.json" in doc["info"]["description"]
    # and the wire does what the document says: a query-parameter 422 is a problem, a frame has its headers
    bad = http.get("/v1/frame", params={"quality": 0})
    assert bad.status_code == 422 and bad.headers["content-type"] == "application/problem+json"
    assert bad.json()["errors"][0]["pointer"] == "#/query/quality"
    frame = http.get("/v1/frame", params={"format": "png"})
    assert set(h.lower() for h in frame_headers) <= set(frame.headers)


def test_websocket_protocol_documented(http):
    api = http.get("/asyncapi.json").json()
    assert api["asyncapi"].startswith("3.") and api["channels"]["frames"]["address"] == "/v1/ws"
    assert {"HelloMessage", "StateMessage", "AckMessage", "CreditMessage", "FrameMessage",
            "ErrorMessage"} <= set(api["components"]["messages"])
    assert "data" in api["components"]["schemas"]["FrameMessage"]["properties"]
    page = http.get("/v1/ws-protocol")
    assert page.status_code == 200 and "credit" in page.text and "/asyncapi.json" in page.text


def test_not_acceptable_is_used(http):
    response = http.get("/v1/state", headers={"Accept": "text/csv"})
    assert response.status_code == 406 and response.json()["kind"] == "not_acceptable"
    assert http.get("/v1/state", headers={"Accept": "text/html,*/*;q=0.8"}).status_code == 200


# --------------------------------------------------------------------------- item 9b

@pytest.mark.parametrize("patch,pointer", [
    ({"camera": {"pitch": "10"}}, "#/camera/pitch"),
    ({"host_frame": "5"}, "#/host_frame"),
    ({"effects": [{"id": "f", "type": "fire", "active": 1}]}, "#/effects/0/active"),
])
def test_numeric_strings_and_ints_for_bools_are_rejected(http, patch, pointer):
    before = state(http)
    for headers, content in (({"Content-Type": "application/json"}, json.dumps(patch).encode()),
                             ({"Content-Type": MSGPACK, "Accept": "application/json"}, msgpack.packb(patch))):
        response = http.patch("/v1/state", content=content, headers=headers)
        assert response.status_code == 422, response.text
        assert response.json()["errors"][0]["pointer"] == pointer
    assert state(http) == before


@pytest.mark.parametrize("body,pointer", [({"sim_time": False}, "#/sim_time"), ({"rate": "2"}, "#/rate"),
                                          ({"paused": 1}, "#/paused")])
def test_clock_changes_are_strict_too(http, body, pointer):
    before = http.get("/v1/clock").json()
    response = http.patch("/v1/clock", json=body)
    assert response.status_code == 422 and response.json()["errors"][0]["pointer"] == pointer, response.text
    after = http.get("/v1/clock").json()
    assert (after["mode"], after["rate"], after["paused"]) == (before["mode"], before["rate"], before["paused"])


def test_time_offset_cannot_leave_the_allowed_years(http):
    before = state(http)
    response = http.patch("/v1/state", json={"time": {"utc": "1800-01-01T00:00:00+23:59"}})
    assert response.status_code == 422 and response.json()["errors"][0]["pointer"] == "#/time/utc"
    assert state(http) == before
    late = http.patch("/v1/state", json={"time": {"utc": "2200-12-31T23:00:00-01:30"}})
    assert late.status_code == 422  # 2201-01-01T00:30Z in UTC
    edge = http.patch("/v1/state", json={"time": {"utc": "1800-01-01T12:00:00+11:00"}})
    assert edge.status_code == 200 and edge.json()["time"]["utc"].startswith("1800-01-01T01:00:00")
    assert http.put("/v1/state", json=edge.json()).status_code == 200  # the stored state passes its own PUT
    assert http.put("/v1/state", json=before).status_code == 200


def test_deeply_nested_msgpack_is_413(http):
    body = b"\x91" * 5000 + b"\x01"
    response = http.patch("/v1/state", content=body, headers={"Content-Type": MSGPACK, "Accept": "application/json"})
    assert response.status_code == 413 and response.json()["kind"] == "limits"


def test_405_carries_allow(http):
    response = http.delete("/v1/state")
    assert response.status_code == 405 and response.json()["kind"] == "method_not_allowed"
    assert {"GET", "PUT", "PATCH"} <= {m.strip() for m in response.headers["allow"].split(",")}
