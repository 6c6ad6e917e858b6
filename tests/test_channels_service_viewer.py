"""The viewer page shows a state's channels side by side, in a real browser (headless Chromium over the
DevTools protocol) against a real server: one image per channel, in the state's order, left to right on
one row, each at its channel's size and showing its own view, all from one frame; without channels the
page goes back to the single MJPEG stream."""

from __future__ import annotations

import httpx
import numpy as np
import pytest

from igserver.protocol.runtime import ServerSettings
from igserver.protocol.testing import LoopbackServer
from igserver.scene import Scene

from cdp import Browser, chromium_path

pytestmark = pytest.mark.skipif(chromium_path() is None, reason="chromium not installed (scripts/test.sh installs it as root)")

# Three windows of one eyepoint over the ground: port looks down (mostly ground), ahead level, starboard
# up (all sky); the gradient sky is blue, the ground yellow-grey.
WINDOW = {"fov_left": 25.0, "fov_right": 25.0, "fov_up": 15.0, "fov_down": 15.0}
CHANNELS = [{"id": "port", "heading": -50.0, "pitch": -25.0, "width": 96, "height": 54, **WINDOW},
            {"id": "ahead", "width": 96, "height": 54, **WINDOW},
            {"id": "stbd", "heading": 50.0, "pitch": 25.0, "width": 80, "height": 45, **WINDOW}]
SCENE = {"camera": {"width": 64, "height": 36, "position": [0.0, 0.0, 2.0]}, "atmosphere": {"model": "gradient"},
         "channels": CHANNELS}


@pytest.fixture(scope="module")
def server():
    with LoopbackServer(Scene.model_validate(SCENE), ServerSettings(keepalive_s=0.25)) as srv:
        yield srv


IMAGES = """Array.from(document.querySelectorAll('#channels figure')).map((f) => {
    const img = f.querySelector('img'), r = img.getBoundingClientRect();
    return {id: f.dataset.channel, w: img.naturalWidth, h: img.naturalHeight, x: r.x, y: r.y, width: r.width,
            kept: img.dataset.kept === '1'};
})"""


def images(page) -> list[dict]:
    """Each channel's figure as shown at a moment when every image has a frame: frames keep coming, and
    an image whose next frame is still decoding reports no size meanwhile (Chromium), so one look may
    fall between two frames."""
    return page.wait_for(f"(() => {{ const s = {IMAGES}; return s.length && s.every((i) => i.w > 0) ? s : null; }})()")


def blueness(shot: np.ndarray) -> float:
    return float(shot[..., 2].mean() - shot[..., 0].mean())


def test_viewer_shows_the_channels_side_by_side(server):
    with Browser() as page:
        page.open(server.url + "/")
        page.wait_for("document.querySelectorAll('#channels figure img').length === 3 && Array.from("
                      "document.querySelectorAll('#channels figure img')).every((i) => i.naturalWidth > 0)", timeout=60)
        shown = images(page)
        assert [s["id"] for s in shown] == ["port", "ahead", "stbd"]
        assert [(s["w"], s["h"]) for s in shown] == [(96, 54), (96, 54), (80, 45)]  # each at its own size
        # one row, left to right, widths in proportion to the channels' pixels
        assert shown[0]["x"] < shown[1]["x"] < shown[2]["x"] and len({round(s["y"]) for s in shown}) == 1
        assert shown[0]["width"] == pytest.approx(shown[1]["width"], rel=0.02)
        assert shown[2]["width"] == pytest.approx(shown[1]["width"] * 80 / 96, rel=0.05)
        assert page.evaluate("document.getElementById('stream').offsetParent") is None  # not displayed
        # each image shows its own view: port (25 deg down) the ground, starboard (25 deg up) the sky
        port = page.screenshot('#channels figure[data-channel="port"] img')
        stbd = page.screenshot('#channels figure[data-channel="stbd"] img')
        assert blueness(stbd) > blueness(port) + 10, (blueness(stbd), blueness(port))
        # frames keep coming, all channels from one frame message
        first = int(page.evaluate("document.getElementById('channels').dataset.frame"))
        httpx.patch(server.url + "/v1/state", json={"host_frame": 77}).raise_for_status()
        page.wait_for("document.getElementById('channels').dataset.hostFrame === '77'")
        assert int(page.evaluate("document.getElementById('channels').dataset.frame")) > first
        # a host turns a channel: its caption follows, the images keep coming on the same socket
        turned = [dict(c, heading=-55.0) if c["id"] == "port" else c for c in CHANNELS]
        httpx.patch(server.url + "/v1/state", json={"channels": turned, "host_frame": 78}).raise_for_status()
        page.wait_for("document.querySelector('#channels figure[data-channel=\"port\"] figcaption')"
                      ".textContent.includes('heading -55')")
        page.wait_for("document.getElementById('channels').dataset.hostFrame === '78'")
        # no channels: back to the camera's MJPEG stream
        httpx.patch(server.url + "/v1/state", json={"channels": []}).raise_for_status()
        page.wait_for("document.getElementById('channels').offsetParent === null && "
                      "document.getElementById('stream').offsetParent !== null "
                      "&& document.getElementById('stream').naturalWidth === 64", timeout=30)


def test_a_closed_channel_socket_reopens_and_the_pictures_stay(server):
    """The channels' WebSocket closes (a server restart, a proxy's timeout): the page opens it again on
    its next look at the channels, and meanwhile each image keeps its last frame - the same elements,
    not blanked and rebuilt."""
    httpx.put(server.url + "/v1/state", json=SCENE).raise_for_status()
    with Browser() as page:
        page.open(server.url + "/")
        page.wait_for("document.querySelectorAll('#channels figure img').length === 3 && Array.from("
                      "document.querySelectorAll('#channels figure img')).every((i) => i.naturalWidth > 0)", timeout=60)
        page.evaluate("document.querySelectorAll('#channels img').forEach((i) => { i.dataset.kept = '1'; }); "
                      "channelView.socket.close()")
        page.wait_for("channelView.socket === null")
        assert all(s["kept"] for s in images(page))
        page.wait_for("channelView.socket !== null && channelView.socket.readyState === 1", timeout=30)
        httpx.patch(server.url + "/v1/state", json={"host_frame": 91}).raise_for_status()
        page.wait_for("document.getElementById('channels').dataset.hostFrame === '91'", timeout=30)
        assert all(s["kept"] for s in images(page))
