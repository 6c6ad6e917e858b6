"""Channels through a real server (docs/channels.md#the-service): GET /v1/channels, a channel's frame and
MJPEG stream, POST /v1/render answering every channel (multipart and msgpack), the WebSocket's hello
``channels`` delivering the channels of one state together under a host that changes the state every
frame, bad channel input refused with nothing changed, the typed client, and per-channel /metrics.

Three small channels (96x54 and 80x45) of the gradient sky over the ground plane: fast on llvmpipe.
"""

from __future__ import annotations

import email.parser
import email.policy
import io
import re
import threading
import time

import httpx
import msgpack
import numpy as np
import pytest
from PIL import Image
from websockets.sync.client import connect

from igserver.client import IGClient, IGError, iter_multipart_jpegs
from igserver.client.cli import main as igclient
from igserver.protocol.runtime import ServerSettings
from igserver.protocol.testing import LoopbackServer
from igserver.scene import Scene

MSGPACK = "application/vnd.msgpack"
CHANNELS = [
    {"id": "port", "heading": -50.0, "pitch": -20.0, "fov_left": 25.0, "fov_right": 25.0, "fov_up": 15.0, "fov_down": 15.0,
     "width": 96, "height": 54},
    {"id": "ahead", "fov_left": 25.0, "fov_right": 25.0, "fov_up": 15.0, "fov_down": 15.0, "width": 96, "height": 54},
    {"id": "stbd", "heading": 50.0, "pitch": 10.0, "fov_left": 25.0, "fov_right": 25.0, "fov_up": 15.0, "fov_down": 15.0,
     "width": 80, "height": 45, "far": 5000.0},
]
IDS = [c["id"] for c in CHANNELS]
SIZES = {c["id"]: (c["width"], c["height"]) for c in CHANNELS}
SCENE = {"camera": {"width": 64, "height": 36, "position": [0.0, 0.0, 2.0]}, "atmosphere": {"model": "gradient"},
         "channels": CHANNELS}


def pack(value) -> bytes:
    return msgpack.packb(value, use_bin_type=True)


def unpack(data: bytes):
    return msgpack.unpackb(data, raw=False)


def jpeg(data: bytes) -> np.ndarray:
    return np.asarray(Image.open(io.BytesIO(data)).convert("RGBA"))


def blueness(rgba: np.ndarray) -> float:
    """Mean blue minus mean red (8-bit levels): the gradient sky is blue (> 0), the ground yellow-grey (< 0)."""
    return float(rgba[..., 2].astype(float).mean() - rgba[..., 0].astype(float).mean())


@pytest.fixture(scope="module")
def server():
    with LoopbackServer(Scene.model_validate(SCENE), ServerSettings(keepalive_s=0.25)) as srv:
        # a frozen IG clock: these tests compare states and frame numbers, which a running sim_time changes
        httpx.patch(srv.url + "/v1/clock", json={"paused": True}).raise_for_status()
        yield srv


@pytest.fixture()
def http(server):
    with httpx.Client(base_url=server.url, timeout=60) as client:
        client.put("/v1/state", json=SCENE).raise_for_status()  # every test starts from the three channels
        yield client


def snapshot(http) -> tuple[dict, str]:
    response = http.get("/v1/state")
    return response.json(), response.headers["x-ig-revision"]


def pointers(response: httpx.Response) -> list[str]:
    return [e["pointer"] for e in response.json().get("errors", [])]


# --------------------------------------------------------------------------- GET /v1/channels

def test_channels_lists_the_states_channels_with_their_sizes(http):
    body = http.get("/v1/channels").json()
    assert [c["id"] for c in body["channels"]] == IDS
    assert {c["id"]: (c["width"], c["height"]) for c in body["channels"]} == SIZES
    port, ahead, stbd = body["channels"]
    assert port["heading"] == -50.0 and stbd["heading"] == 50.0 and not any(c["implicit"] for c in body["channels"])
    # near/far in effect: the camera's where the channel leaves them unset
    assert (ahead["near"], ahead["far"], stbd["far"]) == (0.1, 1_000_000.0, 5000.0)
    assert unpack(http.get("/v1/channels", headers={"Accept": MSGPACK}).content) == body


def test_a_state_without_channels_has_one_implicit_channel(http):
    http.patch("/v1/state", json={"channels": [], "camera": {"fov_y": 60.0}}).raise_for_status()
    (camera,) = http.get("/v1/channels").json()["channels"]
    assert camera["id"] == "" and camera["implicit"] and (camera["width"], camera["height"]) == (64, 36)
    # half-angles of the symmetric camera: fov_y / 2 up and down, atan(tan(30 deg) 64/36) left and right
    assert camera["fov_up"] == camera["fov_down"] == pytest.approx(30.0)
    assert camera["fov_left"] == pytest.approx(np.degrees(np.arctan(np.tan(np.radians(30)) * 64 / 36)), abs=1e-4)
    frame = http.get("/v1/frame")  # and the frame routes serve the camera as before
    assert frame.status_code == 200 and frame.headers["x-ig-channel"] == ""
    assert jpeg(frame.content).shape[:2] == (36, 64)
    assert http.get("/v1/frame", params={"channel": ""}).status_code == 200
    assert http.get("/v1/frame", params={"channel": "ahead"}).status_code == 422


# --------------------------------------------------------------------------- GET /v1/frame?channel=

def test_frame_of_each_channel_same_frame_number(http):
    shots = {}
    for cid in IDS:
        response = http.get("/v1/frame", params={"channel": cid})
        assert response.status_code == 200, response.text
        h = response.headers
        assert h["x-ig-channel"] == cid and (int(h["x-ig-width"]), int(h["x-ig-height"])) == SIZES[cid]
        shots[cid] = (h["x-ig-frame"], h["x-ig-host-frame"], jpeg(response.content))
        assert shots[cid][2].shape[:2] == SIZES[cid][::-1]
    # one still state: every channel is cut from the same frame
    assert len({(frame, host) for frame, host, _ in shots.values()}) == 1
    # the channels look different ways: port, 20 deg lower, shows more of the (yellow-grey) ground
    assert blueness(shots["port"][2]) < blueness(shots["ahead"][2]) - 3
    first = http.get("/v1/frame")  # no channel: the first one
    assert first.headers["x-ig-channel"] == "port" and jpeg(first.content).shape[:2] == (54, 96)
    raw = http.get("/v1/frame", params={"channel": "stbd", "format": "raw"})
    assert len(raw.content) == 80 * 45 * 4


@pytest.mark.parametrize("route", ["/v1/frame", "/v1/stream.mjpg"])
def test_unknown_channel_is_a_problem_naming_the_parameter(http, route):
    before = snapshot(http)
    response = http.get(route, params={"channel": "aft"})
    assert response.status_code == 422
    assert response.headers["content-type"].startswith("application/problem+json")
    assert pointers(response) == ["#/query/channel"]
    assert "'aft'" in response.json()["detail"] and "'port'" in response.json()["detail"]
    assert http.get(route, params={"channel": "x" * 33}).status_code == 422  # longer than any channel id
    assert snapshot(http) == before


# --------------------------------------------------------------------------- MJPEG ?channel=

def test_mjpeg_stream_of_one_channel(http):
    with http.stream("GET", "/v1/stream.mjpg", params={"channel": "stbd", "frames": 2}) as response:
        assert response.status_code == 200
        body = b"".join(response.iter_bytes())
    images = list(iter_multipart_jpegs([body]))
    assert len(images) == 2 and all(jpeg(i).shape[:2] == (45, 80) for i in images)
    assert body.count(b"X-IG-Channel: stbd\r\n") == 2


# --------------------------------------------------------------------------- POST /v1/render

def test_render_answers_every_channel_multipart_and_msgpack(http):
    response = http.post("/v1/render", json={"host_frame": 501})
    assert response.status_code == 200, response.text
    ctype = response.headers["content-type"]
    assert ctype.startswith("multipart/mixed") and response.headers["x-ig-host-frame"] == "501"
    assert response.headers["x-ig-channels"] == ",".join(IDS)
    message = email.parser.BytesParser(policy=email.policy.HTTP).parsebytes(
        f"Content-Type: {ctype}\r\n\r\n".encode() + response.content)
    parts = list(message.iter_parts())
    assert [p["X-IG-Channel"] for p in parts] == IDS
    for part in parts:
        image = jpeg(part.get_payload(decode=True))
        assert image.shape[:2] == SIZES[part["X-IG-Channel"]][::-1]
        assert (int(part["X-IG-Width"]), int(part["X-IG-Height"])) == SIZES[part["X-IG-Channel"]]

    answer = unpack(http.post("/v1/render", json={"host_frame": 502}, headers={"Accept": MSGPACK}).content)
    assert answer["host_frame"] == 502 and list(answer["channels"]) == IDS
    for cid, image in answer["channels"].items():
        assert (image["width"], image["height"]) == SIZES[cid] and jpeg(image["data"]).shape[:2] == SIZES[cid][::-1]

    one = http.post("/v1/render", json={"host_frame": 503}, params={"channel": "ahead", "format": "png"})
    assert one.headers["content-type"] == "image/png" and one.headers["x-ig-channel"] == "ahead"
    assert one.headers["x-ig-host-frame"] == "503"


def test_render_with_an_unknown_channel_changes_nothing(http):
    before = snapshot(http)
    response = http.post("/v1/render", json={"host_frame": 777}, params={"channel": "aft"})
    assert response.status_code == 422 and pointers(response) == ["#/query/channel"]
    assert snapshot(http) == before


# --------------------------------------------------------------------------- WebSocket hello channels

def ws_url(server) -> str:
    return server.url.replace("http", "ws") + "/v1/ws"


def test_ws_channels_of_each_frame_together_under_a_host_changing_every_frame(server):
    """The host turns the camera between 60 deg up (every channel sees sky) and 60 deg down (every channel
    sees ground) with each host frame. Each frame message must carry the asked channels of one state: one
    IG frame number, the host_frame of that state, and all its channels showing that state's sky or
    ground; a channel from a neighbouring state would show the other one."""
    looks = []
    with connect(ws_url(server), compression=None, max_size=1 << 24) as ws:
        ws.send(pack({"type": "hello", "credits": 1, "channels": ["stbd", "port"], "format": "png"}))
        host_frame, frames = 1000, []
        ws.send(pack({"type": "patch", "state": {"host_frame": host_frame, "camera": {"pitch": 60.0}}}))
        while len(frames) < 12:
            message = unpack(ws.recv(30))
            assert message["type"] == "frame", message
            assert list(message["channels"]) == ["stbd", "port"] and "missing" not in message
            frames.append(message)
            mean = {cid: blueness(jpeg(image["data"])) for cid, image in message["channels"].items()}
            looks.append((message["host_frame"], mean))
            # the next state, every frame: up on even host frames, down on odd ones
            host_frame += 1
            ws.send(pack({"type": "patch", "state": {"host_frame": host_frame,
                                                     "camera": {"pitch": 60.0 if host_frame % 2 == 0 else -60.0}}}))
            ws.send(pack({"type": "ack", "frame": message["frame"]}))
    numbers = [m["frame"] for m in frames]
    assert numbers == sorted(numbers) and len(set(numbers)) == len(numbers)
    # (a first frame may show the state before the host's first: not one of these)
    sky = [m for h, m in looks if h >= 1000 and h % 2 == 0]
    ground = [m for h, m in looks if h >= 1000 and h % 2 == 1]
    assert sky and ground, looks
    # every channel of a frame shows its host frame's look: each channel of an even host frame is blue
    # sky, each of an odd one yellow-grey ground
    assert min(min(m.values()) for m in sky) > 5 and max(max(m.values()) for m in ground) < -5, looks


MJPEG_HEAD = re.compile(rb"Content-Length: (\d+)\r\nX-IG-Frame: (\d+)\r\nX-IG-Host-Frame: (\d+)\r\n"
                        rb"X-IG-Render-Ms: [^\r]*\r\nX-IG-Channel: ([^\r]*)\r\n(?:[^\r]*\r\n)*\r\n")


def _read_parts(url: str, channel: str, count: int, out: list) -> None:
    """(IG frame, host_frame, channel, blueness) of ``count`` parts of one channel's MJPEG stream."""
    buffer = b""
    with httpx.stream("GET", url + "/v1/stream.mjpg", params={"channel": channel, "frames": count},
                      timeout=60) as response:
        for chunk in response.iter_bytes():
            buffer += chunk
            while (match := MJPEG_HEAD.search(buffer)) and len(buffer) >= match.end() + int(match[1]):
                data = buffer[match.end():match.end() + int(match[1])]
                out.append((int(match[2]), int(match[3]), match[4].decode(), blueness(jpeg(data))))
                buffer = buffer[match.end() + int(match[1]):]


def test_mjpeg_streams_of_two_channels_show_the_same_frames_under_a_changing_host(server, http):
    """Two MJPEG streams, one per channel, while a host sends a new state every 40 ms, turning the camera
    between sky (even host_frame) and ground (odd): a frame number means the same state in both streams
    (same host_frame), and each part shows its host_frame's look."""
    parts: dict[str, list] = {"port": [], "stbd": []}
    readers = [threading.Thread(target=_read_parts, args=(server.url, cid, 15, parts[cid])) for cid in parts]
    for reader in readers:
        reader.start()
    host_frame = 2000
    while any(reader.is_alive() for reader in readers) and host_frame < 2400:
        pitch = 60.0 if host_frame % 2 == 0 else -60.0
        http.patch("/v1/state", json={"host_frame": host_frame, "camera": {"pitch": pitch}}).raise_for_status()
        host_frame += 1
        time.sleep(0.04)
    for reader in readers:
        reader.join(30)
    assert all(len(p) == 15 for p in parts.values()), {k: len(v) for k, v in parts.items()}
    by_frame = [{frame: host for frame, host, _, _ in p} for p in parts.values()]
    common = set(by_frame[0]) & set(by_frame[1])
    assert common and all(by_frame[0][f] == by_frame[1][f] for f in common), by_frame
    for cid, seen in parts.items():
        assert {c for _, _, c, _ in seen} == {cid}
        assert [f for f, *_ in seen] == sorted(f for f, *_ in seen)
        looks = [(host, blue) for _, host, _, blue in seen if host >= 2000]
        assert len({host for host, _ in looks}) > 3, looks  # the stream followed the host
        assert all((blue > 5) if host % 2 == 0 else (blue < -5) for host, blue in looks), (cid, looks)


def test_ws_hello_channels_rejections_change_nothing(server, http):
    before = snapshot(http)
    with connect(ws_url(server), compression=None) as ws:
        ws.send(pack({"type": "hello", "credits": 0}))  # no frames while the rejections are read
        for channels, pointer in ((["ahead", "aft"], "#/channels/1"), (["ahead", "ahead"], "#/channels/1"),
                                  ([3], "#/channels/0"), ("ahead", "#/channels")):
            ws.send(pack({"type": "hello", "credits": 1, "channels": channels, "id": 5}))
            reply = unpack(ws.recv(10))
            assert reply["type"] == "error" and reply["id"] == 5, reply
            assert [e["pointer"] for e in reply["problem"]["errors"]] == [pointer]
        # a bad channel list in a state message: 422 at its field, nothing changed
        ws.send(pack({"type": "patch", "id": 6, "state": {"channels": [CHANNELS[0], CHANNELS[0]]}}))
        reply = unpack(ws.recv(10))
        assert reply["type"] == "error" and reply["problem"]["errors"][0]["pointer"].startswith("#/state/channels")
        # all channels: [] asks for every channel of each frame
        ws.send(pack({"type": "hello", "credits": 1, "channels": []}))
        message = unpack(ws.recv(30))
        assert list(message["channels"]) == IDS
    assert snapshot(http) == before


# --------------------------------------------------------------------------- bad channel input over REST

BAD = [
    ({"channels": [CHANNELS[0], {**CHANNELS[1], "id": "port"}]}, "#/channels"),
    ({"channels": [{**CHANNELS[0], "width": -96}]}, "#/channels/0/width"),
    ({"channels": [{**CHANNELS[0], "fov_left": 0.0}]}, "#/channels/0/fov_left"),
    ({"channels": [{**CHANNELS[0], "id": f"c{i}"} for i in range(17)]}, "#/channels"),
    ({"channels": [{**CHANNELS[0], "id": f"c{i}", "width": 3840, "height": 2160} for i in range(8)]}, "#/channels"),
]


@pytest.mark.parametrize("patch, pointer", BAD, ids=["duplicate-ids", "negative-width", "zero-fov", "17-channels",
                                                     "over-budget"])
def test_bad_channels_refused_naming_the_field_state_unchanged(http, patch, pointer):
    before = snapshot(http)
    for method, route in (("PATCH", "/v1/state"), ("POST", "/v1/render")):
        response = http.request(method, route, json=patch)
        assert response.status_code == 422, response.text
        assert pointer in pointers(response), response.json()
        assert snapshot(http) == before


# --------------------------------------------------------------------------- the typed client, /metrics

def test_typed_client_fetches_channels(server, http):
    with IGClient(server.url) as ig:
        assert [c["id"] for c in ig.channels()] == IDS
        frame = ig.get_frame(channel="stbd")
        assert (frame.channel, frame.width, frame.height) == ("stbd", 80, 45)
        stepped = ig.render({"host_frame": 900})
        assert list(stepped.channels) == IDS and stepped.channel == "port"
        assert {p.host_frame for p in stepped.channels.values()} == {900}
        assert {p.frame for p in stepped.channels.values()} == {stepped.frame}
        assert stepped.channels["stbd"].rgba().shape == (45, 80, 4)
        assert ig.render({"host_frame": 901}, channel="ahead").channel == "ahead"
        assert len(list(ig.mjpeg(frames=1, channel="ahead"))) == 1
        with ig.stream(credits=1, channels=["ahead", "stbd"]) as stream:
            frame = stream.recv()
            assert list(frame.channels) == ["ahead", "stbd"] and frame.channels["stbd"].width == 80
        with pytest.raises(IGError) as refused:
            ig.get_frame(channel="aft")
        assert refused.value.status == 422


def test_metrics_count_frames_per_channel(server, http):
    http.post("/v1/render", json={"host_frame": 1234}).raise_for_status()
    metrics = server.runtime.metrics
    counts = [metrics.value("igserver_channel_frames_rendered_total", channel=cid) for cid in IDS]
    assert counts[0] and len(set(counts)) == 1, counts  # frame lock in one process: equal counts
    assert metrics.value("igserver_channels") == 3
    text = http.get("/metrics").text
    assert 'igserver_channel_frames_rendered_total{channel="ahead"}' in text


def test_igclient_channels_frame_and_record(server, http, tmp_path, capsys):
    url = ["--url", server.url]
    assert igclient(url + ["channels"]) == 0
    assert [line.split("\t")[0] for line in capsys.readouterr().out.splitlines()] == IDS
    assert igclient(url + ["frame", "--channel", "stbd", str(tmp_path / "stbd.png")]) == 0
    assert Image.open(tmp_path / "stbd.png").size == (80, 45)
    assert igclient(url + ["record", "--png-dir", str(tmp_path / "rec"), "--frames", "2", "--channel", "ahead"]) == 0
    assert [Image.open(p).size for p in sorted((tmp_path / "rec").iterdir())] == [(96, 54)] * 2
    assert igclient(url + ["frame", "--channel", "aft", str(tmp_path / "x.png")]) != 0


def test_ws_channels_that_leave_the_state_are_reported_missing(server, http):
    with connect(ws_url(server), compression=None, max_size=1 << 24) as ws:
        ws.send(pack({"type": "hello", "credits": 1, "channels": ["stbd", "port"]}))
        assert list(unpack(ws.recv(30))["channels"]) == ["stbd", "port"]
        http.patch("/v1/state", json={"host_frame": 610, "channels": CHANNELS[:2]}).raise_for_status()
        while True:
            ws.send(pack({"type": "ack"}))
            message = unpack(ws.recv(30))
            if message["host_frame"] == 610:
                break
        assert list(message["channels"]) == ["port"] and message["missing"] == ["stbd"]


def test_raw_limit_counts_every_channel_of_a_message(server, http, monkeypatch):
    """Three raw channels are 55,872 bytes: over a 50,000-byte limit together, each alone within it."""
    monkeypatch.setattr(server.runtime, "settings", server.runtime.settings.model_copy(
        update={"max_raw_frame_bytes": 50_000}))
    before = snapshot(http)
    response = http.post("/v1/render", json={"host_frame": 620}, params={"format": "raw"})
    assert response.status_code == 413 and pointers(response) == ["#/format"]
    assert snapshot(http) == before
    one = http.post("/v1/render", json={"host_frame": 621}, params={"format": "raw", "channel": "port"})
    assert one.status_code == 200 and len(one.content) == 96 * 54 * 4
