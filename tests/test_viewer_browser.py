"""The viewer page in a real browser (headless Chromium over the DevTools protocol), against a real server.

Issue 9, finding 1: the viewer's fire buttons did nothing visible without a host (no clock) and "stop"
could not put out the scene's own fire (404 swallowed). Here every control is clicked as an operator
would, and both the accepted state and the picture the browser shows are checked.
"""

from __future__ import annotations

import json
import time

import httpx
import numpy as np
import pytest

from igserver.protocol.runtime import ServerSettings
from igserver.protocol.testing import LoopbackServer
from igserver.scene import Scene

from cdp import Browser, chromium_path

pytestmark = pytest.mark.skipif(chromium_path() is None, reason="chromium not installed (scripts/test.sh installs it as root)")

# The night fire scene, small: the fire is the brightest thing in the picture by far.
SCENE = {
    "camera": {"width": 160, "height": 90, "position": [0.0, -30.0, 3.0], "pitch": 4.0, "fov_y": 55.0,
               "exposure_ev": 6.0},
    "time": {"utc": "2026-09-15T21:00:00Z"},
    "atmosphere": {"model": "gradient"},
    "ground": {"enabled": True, "level": 0.0},
    "effects": [{"id": "pool_fire", "type": "fire", "diameter": 6.0, "fade": 0.5, "seed": 3}],
}


@pytest.fixture(scope="module")
def server():
    # a light load for the browser beside it: 8 frames a second while the clock runs, and at most 10 when a
    # test sets a frame-rate target (the stream animates at the target's rate, up to max_fps)
    settings = ServerSettings(keepalive_s=0.25, animation_fps=8, max_fps=10)
    with LoopbackServer(Scene.model_validate(SCENE), settings) as srv:
        yield srv


@pytest.fixture(scope="module")
def page(server):
    with Browser() as browser:
        browser.open(server.url + "/")
        browser.wait_for("document.querySelector('tr[data-effect=\"pool_fire\"]') !== null")
        browser.wait_for("document.getElementById('status').textContent.startsWith('ready')")
        browser.wait_for("document.getElementById('stream').naturalWidth > 0", timeout=60)  # first MJPEG part shown
        yield browser


def row_button(effect_id: str, action: str) -> str:
    return f"document.querySelector('tr[data-effect={json.dumps(effect_id)}] button[data-action={action}]')"


def wait_for_picture(page, condition, timeout: float = 30.0) -> np.ndarray:
    deadline = time.monotonic() + timeout
    while True:
        shot = picture(page)
        if condition(shot) or time.monotonic() > deadline:
            return shot
        time.sleep(0.3)


def picture(page, settle_s: float = 0.0) -> np.ndarray:
    time.sleep(settle_s)
    return page.screenshot("#stream")


def state(server) -> dict:
    return httpx.get(server.url + "/v1/state").json()


def bright_fraction(shot: np.ndarray) -> float:
    # fraction of pixels a flame lights up: the night ground and sky stay far below 120 of 255 at EV 6
    return float((shot.mean(axis=2) > 120).mean())


def test_viewer_stops_and_restarts_the_scenes_own_fire(server, page):
    burning = wait_for_picture(page, lambda s: bright_fraction(s) > 0.002)
    assert bright_fraction(burning) > 0.002, "the fire is not visible in the browser"

    page.evaluate(row_button("pool_fire", "stop") + ".click()")
    deadline = time.monotonic() + 10
    while next(e for e in state(server)["effects"] if e["id"] == "pool_fire")["active"]:
        assert time.monotonic() < deadline, "stop did not reach the server"
        time.sleep(0.1)
    # the IG clock runs without a host: the 0.5 s fade-out completes and the picture goes dark
    out = wait_for_picture(page, lambda s: bright_fraction(s) < 0.0005)
    assert bright_fraction(out) < 0.0005, "stop left the fire burning"
    assert page.evaluate("document.getElementById('error').textContent") == ""

    page.evaluate(row_button("pool_fire", "start") + ".click()")
    lit = wait_for_picture(page, lambda s: bright_fraction(s) > 0.002)
    assert bright_fraction(lit) > 0.002, "start did not relight the fire"
    assert next(e for e in state(server)["effects"] if e["id"] == "pool_fire")["active"]


def test_viewer_shows_errors(server, page):
    # an out-of-range fade: the problem's detail and pointer appear on the page, the state is unchanged
    page.evaluate("(() => { const f = document.querySelector('tr[data-effect=\"pool_fire\"] input');"
                  " f.value = 5000; f.dispatchEvent(new Event('change')); })()")
    text = page.wait_for("(() => { const t = document.getElementById('error').textContent; return t.includes('422') && t; })()")
    assert "#/fade" in text
    assert next(e for e in state(server)["effects"] if e["id"] == "pool_fire")["fade"] == 0.5
    # a 404 is shown, not swallowed: remove an added fire twice (the second click finds nothing)
    page.evaluate("document.getElementById('addFire').click()")
    page.wait_for(f"{row_button('viewer-fire-1', 'remove')} !== null")
    page.evaluate(f"(() => {{ const b = {row_button('viewer-fire-1', 'remove')}; b.click(); b.click(); }})()")
    text = page.wait_for("(() => { const t = document.getElementById('error').textContent; return t.includes('404') && t; })()")
    assert "viewer-fire-1" in text
    assert all(e["id"] != "viewer-fire-1" for e in state(server)["effects"])


def test_viewer_scene_controls_change_state_and_picture(server, page):
    night = picture(page, 0.5)
    # noon UTC at lon 30 E: the sun is high, the picture far brighter than the night one
    page.evaluate("(() => { const h = document.getElementById('hour'); h.value = 10; h.dispatchEvent(new Event('change')); })()")
    page.wait_for("document.getElementById('hourOut').textContent === '10:00'")
    assert state(server)["time"]["utc"].startswith("2026-09-15T10:00")
    page.evaluate("(() => { const w = document.getElementById('wind'); w.value = 12; w.dispatchEvent(new Event('change')); })()")
    page.evaluate("(() => { const v = document.getElementById('vis'); v.value = 3; v.dispatchEvent(new Event('change')); })()")
    deadline = time.monotonic() + 10
    while not (state(server)["weather"]["wind_speed"] == 12 and state(server)["atmosphere"]["visibility"] == 1000):
        assert time.monotonic() < deadline, state(server)
        time.sleep(0.1)
    # the camera exposure is fixed (EV 6): daylight saturates most of the frame
    day = wait_for_picture(page, lambda s: s.mean() > night.mean() + 60)
    assert day.mean() > night.mean() + 60, (night.mean(), day.mean())


def test_viewer_shows_readiness_and_clock(server, page):
    status = page.evaluate("document.getElementById('status').textContent")
    assert status.startswith("ready") and "frames" in status
    page.evaluate("document.getElementById('clockPause').click()")
    page.wait_for("document.getElementById('clock').textContent.includes('paused')")
    assert httpx.get(server.url + "/v1/clock").json()["paused"] is True
    page.evaluate("document.getElementById('clockPause').click()")
    page.wait_for("!document.getElementById('clock').textContent.includes('paused')")
    assert httpx.get(server.url + "/v1/clock").json()["paused"] is False


def test_viewer_shows_the_operating_point(server, page):
    page.wait_for("document.getElementById('quality').textContent.startsWith('scale 1 ')")
    # 240 fps at 640x360 is out of reach on llvmpipe: the cheapest point, said so (at 160x90 the cheapest
    # point's 80x45 frame can take under the 4.2 ms budget, and the target is met now and then)
    httpx.patch(server.url + "/v1/state", json={"quality": {"target_fps": 240},
                                                "camera": {"width": 640, "height": 360}}).raise_for_status()
    try:
        page.wait_for("document.getElementById('quality').textContent.includes('not met')", timeout=30)
        assert "holding 240 fps" in page.evaluate("document.getElementById('quality').textContent")
    finally:
        httpx.patch(server.url + "/v1/state", json={"quality": {"target_fps": 0},
                                                    "camera": {"width": 160, "height": 90}}).raise_for_status()


def mouse(page, kind: str, x: float, y: float) -> None:
    page.send("Input.dispatchMouseEvent", type=kind, x=x, y=y, button="left", buttons=1 if kind != "mouseReleased" else 0,
              clickCount=1)


def test_viewer_slider_drag_is_not_reset_by_the_refresh(server, page):
    httpx.patch(server.url + "/v1/state", json={"weather": {"wind_speed": 6.0}}).raise_for_status()
    page.wait_for("document.getElementById('wind').value === '6'")
    x, y, width, height = page.evaluate(
        "(() => { const w = document.getElementById('wind'); w.scrollIntoView({block: 'center'});"
        " const r = w.getBoundingClientRect(); return [r.x, r.y, r.width, r.height]; })()")
    y += height / 2
    mouse(page, "mousePressed", x + 0.075 * width, y)  # near 6 m/s
    for fraction in (0.2, 0.4, 0.55):  # dragged to ~44 m/s, and held there
        mouse(page, "mouseMoved", x + fraction * width, y)
    dragged = page.evaluate("document.getElementById('wind').value")
    assert 35 <= float(dragged) <= 50, dragged
    # the label follows the drag, and the once-a-second refresh leaves the held slider alone
    page.wait_for(f"document.getElementById('windOut').textContent === {json.dumps(dragged)}", timeout=5)
    time.sleep(1.6)
    assert page.evaluate("document.getElementById('wind').value") == dragged
    assert page.evaluate("document.getElementById('windOut').textContent") == dragged
    mouse(page, "mouseReleased", x + 0.55 * width, y)
    deadline = time.monotonic() + 10
    while state(server)["weather"]["wind_speed"] != float(dragged):
        assert time.monotonic() < deadline, state(server)["weather"]
        time.sleep(0.1)
    time.sleep(1.5)  # refreshed since: the server's value, the same
    assert page.evaluate("document.getElementById('wind').value") == dragged


def test_viewer_slider_ranges_come_from_the_schema(server, page):
    page.wait_for("document.getElementById('wind').dataset.ranged === 'schema'")
    assert page.evaluate("document.getElementById('wind').max") == "80"
    httpx.patch(server.url + "/v1/state", json={"weather": {"wind_speed": 72.0}}).raise_for_status()
    page.wait_for("document.getElementById('wind').value === '72'")  # not clamped to a range of its own
    assert page.evaluate("document.getElementById('windOut').textContent") == "72"
    low, high = page.evaluate("[document.getElementById('vis').min, document.getElementById('vis').max]")
    assert 10 ** float(low) == pytest.approx(50) and 10 ** float(high) == pytest.approx(200_000)
    httpx.patch(server.url + "/v1/state", json={"weather": {"wind_speed": 6.0}}).raise_for_status()


def test_viewer_shows_one_line_for_one_mistake(server, page):
    page.evaluate("(() => { const f = document.querySelector('tr[data-effect=\"pool_fire\"] input');"
                  " f.value = 9999; f.dispatchEvent(new Event('change')); })()")
    text = page.wait_for("(() => { const t = document.getElementById('error').textContent; return t.includes('422') && t; })()")
    lines = [line for line in text.splitlines() if line.strip()]
    assert len(lines) == 2 and lines[1].startswith("#/fade:"), lines  # what was asked and what was wrong
    page.evaluate("document.querySelector('tr[data-effect=\"pool_fire\"] input').blur()")
