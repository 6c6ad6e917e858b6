"""Host water-height queries through the protocol: REST, WebSocket, validation (no render process:
the query is CPU maths on the accepted state)."""

from __future__ import annotations

import msgpack
import numpy as np
import pytest
from fastapi.testclient import TestClient

from igserver.protocol.app import create_app
from igserver.protocol.routers.query import MAX_QUERY_POINTS
from igserver.scene.model import Scene
from igserver.water import sea_surface

STATE = {"ocean": {"enabled": True, "level": 2.5}, "weather": {"wind_speed": 11.0}, "time": {"sim_time": 321.0}}


@pytest.fixture(scope="module")
def client():
    return TestClient(create_app(scene=Scene.model_validate(STATE)), base_url="http://127.0.0.1")


def expected(points, t):
    scene = Scene.model_validate(STATE)
    return sea_surface(scene.ocean, scene.weather).query(np.asarray(points, dtype=float), t)


def test_rest_query_matches_the_wave_module(client):
    points = [[0.0, 0.0], [120.5, -33.0], [1e5, 2e5]]
    reply = client.post("/v1/query/water-height", json={"points": points})
    assert reply.status_code == 200
    body = reply.json()
    # None given: the IG clock's sim_time now (it starts at the state's 321 s and runs in free mode).
    assert 321.0 <= body["sim_time"] < 321.0 + 60.0
    ref = expected(points, body["sim_time"])
    # ENU z, the level included; answers rounded to 7 decimals (REPLY_DECIMALS): half a step, 5e-8
    # (+1e-12: float64 rounding of the sum and of the decimal)
    assert np.allclose(body["height"], ref["height"] + 2.5, rtol=0, atol=5e-8 + 1e-12)
    assert np.allclose(body["normal"], ref["normal"], rtol=0, atol=5e-8 + 1e-12)
    assert np.allclose(body["velocity"], ref["velocity"], rtol=0, atol=5e-8 + 1e-12)
    at = client.post("/v1/query/water-height", json={"points": points, "sim_time": 1e9}).json()
    assert at["sim_time"] == 1e9 and np.allclose(at["height"], expected(points, 1e9)["height"] + 2.5)


@pytest.mark.parametrize("body,pointer", [
    ({"points": []}, "#/points"),
    ({"points": [[0.0, 0.0]] * (MAX_QUERY_POINTS + 1)}, "#/points"),
    ({"points": [[0.0]]}, "#/points/0"),
    ({"points": [[0.0, 0.0]], "sim_time": -1.0}, "#/sim_time"),
    ({"points": [[0.0, 0.0]], "extra": 1}, "#/extra"),
    ({"points": [[1e12, 0.0]]}, "#/points/0/0"),
])
def test_rest_query_rejects_bad_input(client, body, pointer):
    reply = client.post("/v1/query/water-height", json=body)
    assert reply.status_code == 422  # over the point bound too: only a body over the byte limit is 413
    problem = reply.json()
    assert any(e["pointer"].startswith(pointer) for e in problem.get("errors", []))


def test_query_without_sea_is_a_conflict():
    client = TestClient(create_app(scene=Scene()), base_url="http://127.0.0.1")
    reply = client.post("/v1/query/water-height", json={"points": [[0.0, 0.0]]})
    assert reply.status_code == 409


def test_websocket_query(client):
    with client.websocket_connect("ws://127.0.0.1/v1/ws") as ws:
        ws.send_bytes(msgpack.packb({"type": "query", "query": "water-height", "points": [[5.0, 6.0]],
                                     "sim_time": 40.0, "id": 9}))
        while True:
            message = msgpack.unpackb(ws.receive_bytes())
            if message.get("type") != "frame":
                break
        assert message["type"] == "query_result" and message["id"] == 9
        assert message["height"][0] == pytest.approx(expected([[5.0, 6.0]], 40.0)["height"][0] + 2.5, abs=5e-8 + 1e-12)
        ws.send_bytes(msgpack.packb({"type": "query", "query": "water-height", "points": [], "id": 10}))
        while True:
            message = msgpack.unpackb(ws.receive_bytes())
            if message.get("type") != "frame":
                break
        assert message["type"] == "error" and message["id"] == 10


@pytest.mark.parametrize("fmt", ["json", "msgpack"])
def test_rest_query_rejects_non_finite_points_with_their_pointer(client, fmt):
    """The codec's fast path over rows of numbers still finds a NaN or an Infinity and names it."""
    points = [[0.0, 1.0], [2.0, float("nan")], [float("inf"), 3.0]]
    if fmt == "json":
        import json
        reply = client.post("/v1/query/water-height", content=json.dumps({"points": points}),
                            headers={"content-type": "application/json"})
    else:
        reply = client.post("/v1/query/water-height", content=msgpack.packb({"points": points}),
                            headers={"content-type": "application/vnd.msgpack", "accept": "application/json"})
    assert reply.status_code == 422
    errors = reply.json()["errors"]  # the walk reports the first bad number it meets (one of the two)
    assert len(errors) == 1 and errors[0]["pointer"] in ("#/points/1/1", "#/points/2/0")


def test_codec_fast_path_keeps_depth_and_type_checks():
    from igserver.protocol.codec import Limits, check_tree
    from igserver.protocol.problems import ProblemError

    check_tree({"points": [[1.0, 2]]}, Limits(max_depth=3))  # numbers at depth 3: allowed
    with pytest.raises(ProblemError, match="nesting deeper"):
        check_tree({"points": [[1.0, 2.0]]}, Limits(max_depth=2))  # the row's numbers sit at depth 3
    with pytest.raises(ProblemError, match="binary"):
        check_tree({"points": [[1.0, b"x"]]})
    with pytest.raises(ProblemError, match="array longer"):
        check_tree({"points": [[1.0] * 5]}, Limits(max_array=4))
