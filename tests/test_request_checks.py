"""Request checks at the protocol edge, in process (no render process: nothing here draws a frame).

Query booleans, error pointers, effect deletion and its slots, the water query's point bound, the
documentation pages, tokens, and the render budget's boundary where a fire's smoke decides.
"""

from __future__ import annotations

import re

import pytest
from fastapi.testclient import TestClient
from pydantic import ValidationError

from igserver.protocol.app import create_app
from igserver.protocol.routers.query import MAX_QUERY_POINTS
from igserver.protocol.settings import ServerSettings
from igserver.scene.model import MAX_EFFECTS, Scene

SMALL = {"camera": {"width": 64, "height": 36}, "atmosphere": {"model": "gradient"}}


def make_client(tree: dict | None = None, settings: ServerSettings | None = None) -> TestClient:
    app = create_app(scene=Scene.model_validate(tree or SMALL), settings=settings)
    return TestClient(app, base_url="http://127.0.0.1")


@pytest.fixture()
def client():
    client = make_client()
    # a frozen IG clock: the tests compare whole states, which a running sim_time changes
    client.patch("/v1/clock", json={"paused": True}).raise_for_status()
    return client


def state_and_revision(client):
    response = client.get("/v1/state")
    return response.json(), response.headers["x-ig-revision"]


def advance_clock(client, seconds: float) -> None:
    now = client.get("/v1/clock").json()["sim_time"]
    client.patch("/v1/clock", json={"sim_time": now + seconds}).raise_for_status()


# --------------------------------------------------------------------------- query booleans

@pytest.mark.parametrize("text", ["yes", "no", "on", "off", "t", "2", ""])
def test_render_replace_flag_is_strict(client, text):
    before = state_and_revision(client)
    response = client.post("/v1/render", params={"replace": text}, json={})
    assert response.status_code == 422, response.text
    problem = response.json()
    assert [e["pointer"] for e in problem["errors"]] == ["#/query/replace"]
    assert "true, false, 1 or 0" in problem["detail"]
    assert state_and_revision(client) == before


def test_delete_immediate_flag_is_strict(client):
    client.post("/v1/effects", json={"id": "fx"}).raise_for_status()
    response = client.delete("/v1/effects/fx", params={"immediate": "yes"})
    assert response.status_code == 422 and response.json()["errors"][0]["pointer"] == "#/query/immediate"
    assert client.get("/v1/effects/fx").json()["active"] is True  # nothing changed
    assert client.delete("/v1/effects/fx", params={"immediate": "0"}).status_code == 202
    assert client.delete("/v1/effects/fx", params={"immediate": "True"}).status_code == 204


# --------------------------------------------------------------------------- error pointers

def assert_pointers_agree(problem: dict, pointer: str) -> None:
    assert [e["pointer"] for e in problem["errors"]] == [pointer], problem
    assert problem["detail"].startswith(pointer + ":"), problem


def test_effect_route_errors_and_detail_give_one_pointer(client):
    # pointers of the effect routes point into the request body, which is the effect
    assert_pointers_agree(client.post("/v1/effects", json={"id": "p", "profile": "missing"}).json(), "#/profile")
    client.post("/v1/effects", json={"id": "q"}).raise_for_status()
    assert_pointers_agree(client.patch("/v1/effects/q", json={"diameter": -1.0}).json(), "#/diameter")
    # the same effect in a whole state: the pointer into the state
    bad = client.patch("/v1/state", json={"effects": [{"id": "p", "profile": "missing"}]}).json()
    assert_pointers_agree(bad, "#/effects/0/profile")


def test_effect_pointer_prefix_is_a_whole_index(client, tmp_path, monkeypatch):
    # effect 10's profile asset disappears: changing effect 1 then fails on effect 10, whose pointer
    # stays its own ("#/effects/1" is a prefix of "#/effects/10/profile" as text, not as a pointer)
    from PIL import Image

    (tmp_path / "profiles").mkdir()
    Image.new("RGBA", (8, 16)).save(tmp_path / "profiles" / "gone.png")
    monkeypatch.setenv("IGSERVER_ASSETS", str(tmp_path))
    for index in range(11):
        client.post("/v1/effects", json={"id": f"e{index}", **({"profile": "gone"} if index == 10 else {})}
                    ).raise_for_status()
    (tmp_path / "profiles" / "gone.png").unlink()
    bad = client.patch("/v1/effects/e1", json={"intensity": 2.0}).json()
    assert_pointers_agree(bad, "#/effects/10/profile")


@pytest.mark.parametrize("bathymetry", [
    {"type": "map", "map": "nosuch"},  # no such asset
    {"type": "map"},  # a map type without its map
    {"type": "map", "map": "../island"},  # not a name
])
def test_bathymetry_map_errors_point_at_the_map(client, bathymetry):
    before = state_and_revision(client)
    response = client.patch("/v1/state", json={"ocean": {"bathymetry": bathymetry}})
    assert response.status_code == 422
    assert_pointers_agree(response.json(), "#/ocean/bathymetry/map")
    assert state_and_revision(client) == before


def test_openapi_bathymetry_map_has_the_asset_name_pattern(client):
    from igserver.assets import ASSET_NAME_PATTERN

    schema = client.get("/openapi.json").json()["components"]["schemas"]["Bathymetry"]["properties"]["map"]
    patterns = [option.get("pattern") for option in schema.get("anyOf", [schema])]
    assert ASSET_NAME_PATTERN in patterns, schema


# --------------------------------------------------------------------------- deleted effects

def listed(client) -> list[str]:
    return [effect["id"] for effect in client.get("/v1/effects").json()]


def test_deleted_effects_free_their_slots_and_leave_the_listing(client):
    for index in range(MAX_EFFECTS):
        assert client.post("/v1/effects", json={"id": f"s{index}", "type": "smoke"}).status_code == 201
    assert client.post("/v1/effects", json={"id": "one-too-many"}).status_code == 422
    for index in range(MAX_EFFECTS):
        assert client.delete(f"/v1/effects/s{index}").status_code == 202
    # fading out, they may still be listed, but their slots are free at once
    assert client.post("/v1/effects", json={"id": "fresh"}).status_code == 201
    assert "fresh" in listed(client) and len(listed(client)) <= MAX_EFFECTS
    advance_clock(client, 10.0)  # past the 3 s fade
    assert listed(client) == ["fresh"]
    assert [e["id"] for e in client.get("/v1/state").json()["effects"]] == ["fresh"]


def test_a_deleted_id_can_be_added_again_at_once(client):
    client.post("/v1/effects", json={"id": "x", "diameter": 2.0}).raise_for_status()
    assert client.delete("/v1/effects/x").status_code == 202
    again = client.post("/v1/effects", json={"id": "x", "diameter": 5.0})
    assert again.status_code == 201 and again.json()["active"] is True and again.json()["diameter"] == 5.0
    advance_clock(client, 10.0)
    assert listed(client) == ["x"]  # the new one stays: only the deleted one was to go
    assert client.get("/v1/effects/x").json()["diameter"] == 5.0


def test_a_reignited_effect_is_not_removed(client):
    client.post("/v1/effects", json={"id": "r"}).raise_for_status()
    client.delete("/v1/effects/r").raise_for_status()
    client.patch("/v1/effects/r", json={"active": True}).raise_for_status()
    advance_clock(client, 10.0)
    assert listed(client) == ["r"]
    # extinguished (PATCH active=false) is not deleted: it stays, to be reignited
    client.patch("/v1/effects/r", json={"active": False}).raise_for_status()
    advance_clock(client, 10.0)
    assert listed(client) == ["r"]


# --------------------------------------------------------------------------- water query bound

def test_water_query_over_1024_points_over_rest():
    client = make_client({**SMALL, "ocean": {"enabled": True}})
    reply = client.post("/v1/query/water-height", json={"points": [[float(i), 0.0] for i in range(1025)]})
    assert reply.status_code == 200 and len(reply.json()["height"]) == 1025
    # over the bound: always 422 with the pointer, however many more (the byte limit is the only 413)
    for count in (MAX_QUERY_POINTS + 1, 2 * MAX_QUERY_POINTS + 1):
        reply = client.post("/v1/query/water-height", json={"points": [[0.0, 0.0]] * count})
        assert reply.status_code == 422, (count, reply.text[:200])
        assert reply.json()["errors"][0]["pointer"] == "#/points"


# --------------------------------------------------------------------------- documentation pages, favicon

def page_urls(html: str) -> list[str]:
    return re.findall(r"""(?:src|href)\s*=\s*["']([^"']+)["']""", html)


@pytest.mark.parametrize("page", ["/docs", "/redoc"])
def test_documentation_pages_load_nothing_from_outside(client, page):
    response = client.get(page)
    assert response.status_code == 200
    urls = page_urls(response.text)
    assert urls and not [u for u in urls if re.match(r"(https?:)?//", u)], urls
    for url in urls:
        asset = client.get(url)
        assert asset.status_code == 200, url
        if url.endswith(".js"):
            assert "cdn.redoc.ly" not in asset.text, url  # ReDoc's footer logo, an image it loads itself
    if page == "/docs":
        assert '"validatorUrl": null' in response.text  # Swagger's validator badge is an outside image


def test_favicon_is_served(client):
    from io import BytesIO

    from PIL import Image

    response = client.get("/favicon.ico")
    assert response.status_code == 200 and response.headers["content-type"].startswith("image/")
    assert len(response.content) < 16_384
    assert Image.open(BytesIO(response.content)).size[0] <= 64


# --------------------------------------------------------------------------- tokens

@pytest.mark.parametrize("blank", ["", "   ", "\t\n"])
def test_a_blank_token_is_no_token(blank, tmp_path):
    assert ServerSettings(token=blank).bearer_token() is None
    token_file = tmp_path / "token"
    token_file.write_text(blank)
    assert ServerSettings(token_file=token_file).bearer_token() is None


def test_a_blank_token_cannot_open_a_network_bind(capsys):
    from igserver.protocol.app import serve

    assert serve(scene_path=None, settings=ServerSettings(host="0.0.0.0", token="   ")) == 2
    assert "without a token" in capsys.readouterr().err


@pytest.mark.parametrize("presented", ["+++", "%20%20%20", "", "%09"])
def test_blank_access_tokens_do_not_pass(presented):
    client = make_client(settings=ServerSettings(token="s3cret"))
    assert client.get(f"/v1/state?access_token={presented}").status_code == 401
    assert client.get("/v1/state", headers={"Authorization": "Bearer    "}).status_code == 401
    assert client.get("/v1/state?access_token=s3cret").status_code == 200


# --------------------------------------------------------------------------- render budget boundary

def fires(count: int, smoky: int = 0) -> dict:
    effects = [{"id": f"f{i}", "diameter": 5.0, "emits_smoke": i < smoky} for i in range(count)]
    return {"camera": {"width": 640, "height": 360}, "quality": {"preset": "high"}, "effects": effects}


def test_a_fires_smoke_decides_the_budget(monkeypatch):
    monkeypatch.delenv("IGSERVER_BUDGET_SCALE", raising=False)
    def fits(tree: dict) -> bool:
        try:
            Scene.model_validate(tree)
        except ValidationError:
            return False
        return True

    most = max(n for n in range(1, MAX_EFFECTS + 1) if fits(fires(n)))  # plain fires: one volume each
    assert 1 < most < MAX_EFFECTS
    Scene.model_validate(fires(most))  # fits
    with pytest.raises(ValidationError) as info:
        Scene.model_validate(fires(most, smoky=1))  # the same fires, one with smoke: one volume more
    errors = info.value.errors()
    assert [e["loc"] for e in errors] == [("effects",)] and "budget" in errors[0]["msg"]
    assert "emits_smoke counts twice" in errors[0]["msg"]
