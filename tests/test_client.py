"""The Python host client (sync and asyncio) and the igclient CLI, against a real server on loopback."""

from __future__ import annotations

import asyncio
import json

import pytest
from PIL import Image

from igserver.client.core import AsyncIGClient, IGClient, IGError, main
from igserver.protocol.runtime import ServerSettings
from igserver.protocol.testing import LoopbackServer
from igserver.scene import Scene, save_scene

W, H = 64, 36


def small_scene(**extra) -> Scene:
    return Scene.model_validate({"camera": {"width": W, "height": H}, "atmosphere": {"model": "gradient"}, **extra})


@pytest.fixture(scope="module")
def server():
    with LoopbackServer(small_scene(), ServerSettings(keepalive_s=0.25)) as srv:
        yield srv


def test_sync_client(server):
    with IGClient(server.url) as ig:
        assert ig.health()["status"] == "ok" and ig.wait_ready()["ready"]
        scene = small_scene(host_frame=5, weather={"wind_speed": 3.0})
        assert ig.put_state(scene) == scene
        assert ig.patch_state({"camera": {"pitch": 10.0}}).camera.pitch == 10.0
        assert ig.get_state().weather.wind_speed == 3.0
        with pytest.raises(IGError) as info:
            ig.patch_state({"camera": {"pitch": float("inf")}})
        assert info.value.status == 422 and info.value.problem["errors"][0]["pointer"] == "#/camera/pitch"
        frame = ig.get_frame("png")
        assert frame.host_frame == 5 and frame.rgba().shape == (H, W, 4)
        rendered = ig.render({"host_frame": 6}, format="raw")
        assert rendered.host_frame == 6 and rendered.rgba().shape == (H, W, 4)
        ig.add_effect({"id": "smoke-1", "type": "smoke"})
        assert ig.patch_effect("smoke-1", {"intensity": 0.5})["intensity"] == 0.5
        assert ig.delete_effect("smoke-1")["active"] is False
        assert ig.delete_effect("smoke-1", immediate=True) is None and ig.effects() == []
        assert "igserver_frames_rendered_total" in ig.metrics()
        with ig.stream(credits=1) as stream:
            stream.send_patch({"host_frame": 7})
            while (frame := stream.recv()).host_frame != 7:
                pass
            stream.send_patch({"camera": {"roll": 999.0}})
            with pytest.raises(IGError):
                while True:
                    stream.recv()


def test_async_client(server):
    async def scenario():
        async with AsyncIGClient(server.url) as ig:
            assert (await ig.ready())["ready"]
            await ig.put_state(small_scene(host_frame=100))
            assert (await ig.patch_state({"host_frame": 101}, minimal=True))["host_frame"] == 101
            assert (await ig.get_state()).host_frame == 101
            assert (await ig.get_frame()).host_frame == 101
            assert (await ig.render({"host_frame": 102})).host_frame == 102
            async with ig.stream(credits=2) as stream:
                await stream.send_patch({"host_frame": 103})
                while (await stream.recv()).host_frame != 103:
                    pass

    asyncio.run(scenario())


def test_cli(server, tmp_path, capsys):
    url = ["--url", server.url]
    scene_file = tmp_path / "scene.toml"
    save_scene(small_scene(host_frame=200, weather={"wind_speed": 11.0}), scene_file)
    assert main(url + ["send", str(scene_file)]) == 0
    assert main(url + ["set", "camera.pitch=4", "host_frame=201"]) == 0
    assert main(url + ["state"]) == 0
    state = json.loads(capsys.readouterr().out.split("\n", 2)[2])
    assert state["camera"]["pitch"] == 4 and state["weather"]["wind_speed"] == 11.0
    assert main(url + ["set", "camera.pitch=900"]) == 2  # rejected: a clear error, exit code 2

    assert main(url + ["frame", str(tmp_path / "f.png")]) == 0
    assert Image.open(tmp_path / "f.png").size == (W, H)

    scenario = tmp_path / "scenario.jsonl"
    scenario.write_text("\n".join(json.dumps({"camera": {"heading": h}}) for h in range(0, 50, 10)))
    assert main(url + ["play", str(scenario), "--rate", "100"]) == 0
    with IGClient(server.url) as ig:
        assert ig.get_state().camera.heading == 40 and ig.get_state().host_frame == 206

    assert main(url + ["record", "--mjpeg", str(tmp_path / "s.mjpg"), "--frames", "2"]) == 0
    assert (tmp_path / "s.mjpg").read_bytes()[:2] == b"\xff\xd8"
    assert main(url + ["record", "--png-dir", str(tmp_path / "png"), "--frames", "2"]) == 0
    assert len(list((tmp_path / "png").glob("*.png"))) == 2

    capsys.readouterr()
    assert main(url + ["bench", "--frames", "5"]) == 0
    out = capsys.readouterr().out
    assert "ws:" in out and "http:" in out and "p99" in out
