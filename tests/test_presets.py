"""Quality presets: the knob table, the one-knob ladder between levels, the auto
controller's hysteresis, and the preset from the scene model (= the protocol) and the CLI."""

from __future__ import annotations

from dataclasses import fields, is_dataclass

import pytest
from pydantic import ValidationError

import igserver.render.volumes.volumes  # noqa: F401 - registers the volumes knobs
from igserver.cli import _scene_from_args, build_parser
from igserver.render import presets
from igserver.scene import Scene

from helpers import tiny


def _differences(a: dict, b: dict) -> list[str]:
    out = []
    for pipeline in a:
        x, y = a[pipeline], b[pipeline]
        if is_dataclass(x) and type(x) is type(y):
            out += [f"{pipeline}.{f.name}" for f in fields(x) if getattr(x, f.name) != getattr(y, f.name)]
        elif x != y:
            out.append(pipeline)
    return out


def test_levels_are_registered_for_the_volumes():
    knobs = presets.registered()["volumes"]
    assert set(knobs) == set(presets.LEVELS)
    # higher levels never have fewer steps, octaves, voxels or a coarser march
    lo, me, hi = (knobs[level] for level in presets.LEVELS)
    assert lo.steps <= me.steps <= hi.steps and lo.octaves <= me.octaves <= hi.octaves
    assert lo.resolution <= me.resolution <= hi.resolution and lo.scale >= me.scale >= hi.scale


def test_register_needs_every_level():
    with pytest.raises(ValueError):
        presets.register("broken", {"low": 1, "medium": 2})


def test_ladder_changes_one_knob_per_rung():
    rungs = presets.ladder()
    names = [r.name for r in rungs]
    assert names[0] == "low" and names[-1] == "high" and "medium" in names
    for a, b in zip(rungs, rungs[1:]):
        assert len(_differences(a.knobs, b.knobs)) == 1, (a.name, b.name)
    for level in presets.LEVELS:
        rung = rungs[names.index(level)]
        assert all(presets.knobs(p, rung) == presets.knobs(p, level) for p in presets.registered())


def test_auto_steps_down_over_target_and_holds_between():
    auto = presets.AutoQuality(target_ms=40.0)
    start = auto.index
    for _ in range(presets.WINDOW_FRAMES):
        auto.observe(60.0)
    assert auto.index == start - 1  # one rung, not a jump to low
    for _ in range(presets.HOLD_FRAMES - 1):
        auto.observe(60.0)
    assert auto.index == start - 1  # held: the new rung's times are not in yet
    # The window after the hold still holds the slow frames: one more rung down, then frames
    # between UP_FRACTION x target and the target: hysteresis, no change however long.
    for _ in range(10 * presets.WINDOW_FRAMES):
        auto.observe(35.0)
    assert auto.index == start - 2
    settled = auto.index
    # Fast frames: climbs back one rung per hold period.
    for _ in range(presets.WINDOW_FRAMES + presets.HOLD_FRAMES):
        auto.observe(5.0)
    assert auto.index > settled


def test_auto_preset_adapts_in_the_renderer(renderer):
    scene = tiny({"ground": {"enabled": False}, "quality": {"preset": "auto", "target_ms": 1.0}}, 16, 16)
    renderer.auto_quality = None
    first = renderer.render(scene).quality
    for _ in range(presets.WINDOW_FRAMES + 1):
        result = renderer.render(scene)
    # A 1 ms target cannot be met on llvmpipe: the controller stepped down from medium.
    assert first == "medium" and result.quality != "medium"
    assert renderer.auto_quality.index < [r.name for r in presets.ladder()].index("medium")


def test_preset_and_target_in_the_scene_model():
    assert Scene.model_validate({"quality": {"preset": "auto", "target_ms": 33.3}}).quality.preset == "auto"
    for bad in ({"preset": "ultra"}, {"target_ms": 0.0}, {"target_ms": float("nan")}, {"target_ms": "fast"}):
        with pytest.raises(ValidationError):
            Scene.model_validate({"quality": bad})


@pytest.mark.parametrize("command", ["render", "bench", "serve"])
def test_preset_flag_on_the_cli(command):
    argv = {"render": ["render", "--scene", "sky_only", "--out", "x.png"], "bench": ["bench"],
            "serve": ["serve"]}[command] + ["--preset", "low"]
    args = build_parser().parse_args(argv)
    assert args.preset == "low"
    if command == "render":
        assert _scene_from_args(args).quality.preset == "low"
    with pytest.raises(SystemExit):
        build_parser().parse_args(argv[:-1] + ["ultra"])


@pytest.mark.parametrize("name,expected", [
    ("sky_only", ["sky", "post"]),
    ("demo", ["surfaces", "water", "sky", "depth_copy", "volumes", "post"]),
    ("night_fire", ["surfaces", "sky", "depth_copy", "volumes", "post"]),
])
def test_example_scene_pass_lists_unchanged_at_every_preset(renderer, name, expected):
    from igserver.render.graph import plan_passes
    from igserver.scene import apply_patch, load_scene

    known = {"surfaces", "water", "sky", "depth_copy", "volumes", "post"}  # passes other pipelines add
    for preset in (*presets.LEVELS, "auto"):  # (precipitation, ...) may join; these keep their order
        scene = apply_patch(load_scene(name), {"quality": {"preset": preset}})
        assert [p for p in plan_passes(scene) if p in known] == expected
        assert [p for p in renderer.graph.plan(scene) if p in known] == expected
