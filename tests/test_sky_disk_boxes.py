"""The sky pass keeps the sun's and moon's scissor boxes per exact view, directions and field of
view: a still camera reuses them, a turned camera or another sun gets boxes computed afresh, equal
to disk_box's."""

from helpers import tiny
from igserver.render.sky.sky import MOON_BOX_RAD, SUN_BOX_RAD, disk_box
from igserver.scene import apply_patch


def _direct(frame):
    c = frame.celestial
    return [b for b in (disk_box(frame, c.sun_dir, SUN_BOX_RAD), disk_box(frame, c.moon_dir, MOON_BOX_RAD))
            if b is not None]


def test_boxes_follow_view_and_sun(renderer):
    from igserver.render.frame import build_frame
    sky = renderer.graph.passes["sky"]
    base = tiny({"camera": {"heading": 230.0, "pitch": 5.0, "fov_y": 40.0},
                 "time": {"sun_override": {"elevation": 8.0, "azimuth": 230.0}}})
    seen = []
    for patch in ({}, {"time": {"sim_time": 3.0}}, {"camera": {"heading": 236.0}},
                  {"time": {"sun_override": {"elevation": 12.0, "azimuth": 226.0}}}, {"camera": {"fov_y": 30.0}}):
        scene = apply_patch(base, patch)
        frame = build_frame(renderer.ctx, scene)
        boxes = sky._disk_boxes(frame)
        assert boxes == _direct(frame) and boxes, patch
        seen.append(boxes)
    assert seen[1] is seen[0]  # the clock alone: the same boxes, not computed again
    assert seen[2] != seen[0] and seen[3] != seen[2] and seen[4] != seen[3]
