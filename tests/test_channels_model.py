"""Channels in the scene model (docs/channels.md): validation with the field named, the render budget
over every channel, patches, scene files, and the channel's camera (no GL)."""

from __future__ import annotations

import math
import tomllib

import numpy as np
import pytest
from pydantic import ValidationError

from igserver.render.camera import body_to_world, frustum_tangents, make_view
from igserver.render.channels import channel_camera, channel_scene, euler_of, side_by_side
from igserver.scene import Scene, apply_patch, dumps_scene, patch_from_assignments
from igserver.scene.channels import mosaic_layout, total_pixels


def bridge(width=640, height=360, **extra) -> list[dict]:
    return [dict(id=cid, heading=h, width=width, height=height, **extra)
            for cid, h in (("port", -60.0), ("ahead", 0.0), ("starboard", 60.0))]


def paths(exc: ValidationError) -> list[str]:
    return [".".join(str(p) for p in e["loc"]) for e in exc.errors()]


def test_three_channels_accepted_with_16_9_defaults():
    scene = Scene(channels=bridge())
    assert [c.id for c in scene.channels] == ["port", "ahead", "starboard"]
    c = scene.channels[0]
    aspect = (math.tan(math.radians(c.fov_left)) + math.tan(math.radians(c.fov_right))) / (
        math.tan(math.radians(c.fov_up)) + math.tan(math.radians(c.fov_down)))
    assert aspect == pytest.approx(16 / 9, rel=1e-3)
    assert Scene().channels == []
    assert mosaic_layout(scene) == ((1920, 360), [("port", 0, 640, 360), ("ahead", 640, 640, 360),
                                                   ("starboard", 1280, 640, 360)])


BAD = [
    ("duplicate-id", [dict(id="a"), dict(id="a")], "channels"),
    ("zero-width", [dict(id="a", width=0)], "channels.0.width"),
    ("negative-height", [dict(id="a", height=-360)], "channels.0.height"),
    ("zero-half-angle", [dict(id="a", fov_left=0.0)], "channels.0.fov_left"),
    ("negative-half-angle", [dict(id="a", fov_down=-5.0)], "channels.0.fov_down"),
    ("half-angle-90", [dict(id="a", fov_up=90.0)], "channels.0.fov_up"),
    ("nan-heading", [dict(id="a", heading=math.nan)], "channels.0.heading"),
    ("inf-fov", [dict(id="a", fov_right=math.inf)], "channels.0.fov_right"),
    ("bad-id", [dict(id="port side")], "channels.0.id"),
    ("long-id", [dict(id="x" * 33)], "channels.0.id"),
    ("empty-id", [dict(id="")], "channels.0.id"),
    ("seventeen", [dict(id=f"c{i}", width=16, height=16) for i in range(17)], "channels"),
    ("unknown-field", [dict(id="a", zoom=2)], "channels.0.zoom"),
    ("near-beyond-far", [dict(id="a", near=10.0, far=5.0)], "channels.0"),
    ("near-beyond-camera-far", [dict(id="a", near=2000.0)], "channels"),
    # 2 x 3840x2160 = 16.6 Mpx > the 12.5 Mpx a frame without effects may cost (one of them fits)
    ("over-budget", [dict(id=f"c{i}", width=3840, height=2160) for i in range(2)], "channels"),
]


@pytest.mark.parametrize("channels, path", [b[1:] for b in BAD], ids=[b[0] for b in BAD])
def test_bad_channels_refused_naming_the_field(channels, path):
    tree = {"channels": channels, "camera": {"far": 1000.0}}
    with pytest.raises(ValidationError) as info:
        Scene.model_validate(tree)
    assert path in paths(info.value), info.value


def test_budget_counts_every_channel():
    one = Scene(channels=[dict(id="big", width=3840, height=2160)])
    assert total_pixels(one) == 3840 * 2160
    with pytest.raises(ValidationError) as info:
        apply_patch(one, {"channels": [dict(id=f"c{i}", width=3840, height=2160) for i in range(2)]})
    message = info.value.errors()[0]["msg"]
    assert "2 channels" in message and "render budget" in message
    # the camera's own size no longer counts while there are channels
    assert apply_patch(one, {"camera": {"width": 7680, "height": 4320}}).camera.width == 7680


def test_patch_replaces_the_list_and_set_addresses_one_item():
    scene = Scene(channels=bridge())
    smaller = apply_patch(scene, {"channels": [dict(id="only")]})
    assert [c.id for c in smaller.channels] == ["only"]
    patch = patch_from_assignments(["channels.2.heading=70"], base=scene.model_dump(mode="python"))
    turned = apply_patch(scene, patch)
    assert [c.heading for c in turned.channels] == [-60.0, 0.0, 70.0]
    assert apply_patch(scene, {"channels": []}).channels == []
    # a refused patch leaves the state as it was (the caller keeps the old scene)
    with pytest.raises(ValidationError):
        apply_patch(scene, {"channels": [dict(id="a"), dict(id="a")]})
    assert len(scene.channels) == 3


def test_wire_and_file_round_trip():
    scene = Scene(channels=bridge(near=0.5))
    assert apply_patch(Scene(), scene.model_dump(mode="json"), strict=True) == scene
    assert Scene.model_validate(tomllib.loads(dumps_scene(scene))) == scene


@pytest.mark.parametrize("cam, offset", [((0, 0, 0), (30, 0, 0)), ((90, 10, 5), (-60, 5, 0)),
                                         ((200, -30, 20), (45, -20, 10)), ((10, 0, 0), (0, 90, 0))])
def test_channel_orientation_is_the_composed_rotation(cam, offset):
    """R_channel = R_camera . R_offset: the offsets turn in the camera's own frame."""
    scene = Scene(camera=dict(heading=cam[0], pitch=cam[1], roll=cam[2]),
                  channels=[dict(id="c", heading=offset[0], pitch=offset[1], roll=offset[2])])
    camera = channel_camera(scene.camera, scene.channels[0])
    expected = body_to_world(*cam) @ body_to_world(*offset)
    assert np.allclose(body_to_world(camera.heading, camera.pitch, camera.roll), expected, atol=1e-12)
    assert np.allclose(body_to_world(*euler_of(expected)), expected, atol=1e-12)


def test_channel_frustum_is_asymmetric_from_the_half_angles():
    scene = Scene(channels=[dict(id="c", fov_left=10, fov_right=40, fov_up=5, fov_down=25, width=320, height=200,
                                 near=2.0)])
    sub = channel_scene(scene, scene.channels[0])
    assert sub.channels == [] and (sub.camera.width, sub.camera.height, sub.camera.near) == (320, 200, 2.0)
    tangents = frustum_tangents(sub.camera)
    assert np.allclose(tangents, [-math.tan(math.radians(10)), math.tan(math.radians(40)),
                                  -math.tan(math.radians(25)), math.tan(math.radians(5))])
    # glFrustum at unit distance: a point on the right edge plane projects to NDC x = 1
    view = make_view(sub.camera)
    right_edge = view.rotation @ np.array([math.tan(math.radians(40)), 1.0, 0.0])
    clip = view.view_proj @ np.append(right_edge, 1.0)
    assert clip[0] / clip[3] == pytest.approx(1.0)


def test_adjacent_channels_share_their_edge_rays():
    """Headings -a and +a with fov_right = fov_left = a: the left channel's right edge plane is the
    right channel's left edge plane."""
    scene = Scene(channels=[dict(id="l", heading=-20, fov_left=20, fov_right=20),
                            dict(id="r", heading=20, fov_left=20, fov_right=20)])
    left, right = (make_view(channel_camera(scene.camera, c)) for c in scene.channels)
    edge = left.rotation @ np.array([math.tan(math.radians(20)), 1.0, 0.3])
    for view, ndc_x in ((left, 1.0), (right, -1.0)):
        clip = view.view_proj @ np.append(edge, 1.0)
        assert clip[0] / clip[3] == pytest.approx(ndc_x, abs=1e-12)


def test_side_by_side_pads_shorter_channels():
    a = np.full((4, 3, 4), 7, np.uint8)
    b = np.full((2, 5, 4), 9, np.uint8)
    out = side_by_side([a, b])
    assert out.shape == (4, 8, 4) and np.all(out[:, :3] == 7) and np.all(out[:2, 3:] == 9)
    assert np.all(out[2:, 3:] == 0)


def test_the_docs_toml_snippet_is_a_valid_scene():
    from pathlib import Path

    text = (Path(__file__).parent.parent / "docs" / "channels.md").read_text()
    snippet = text.split("```toml\n", 1)[1].split("```", 1)[0]
    scene = Scene.model_validate(tomllib.loads(snippet))
    assert [c.id for c in scene.channels] == ["port", "ahead", "starboard"]
