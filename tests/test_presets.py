"""Quality presets: the knob table, the one-knob ladder between levels, the auto preset in the
renderer (the controller itself: test_overload.py), and the preset from the scene model (= the
protocol) and the CLI."""

from __future__ import annotations

from dataclasses import fields, is_dataclass

import pytest
from pydantic import ValidationError

import igserver.render.volumes.settings  # noqa: F401 - registers the volumes knobs
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


def test_auto_preset_adapts_in_the_renderer(renderer):
    from igserver.render import overload

    # The sea: its mesh's vertex work and the host's frame setup alone take a few ms at any size (a
    # 16x16 sky frame now and then met the 1 ms target on an idle machine).
    scene = tiny({"ground": {"enabled": False}, "ocean": {"enabled": True},
                  "quality": {"preset": "auto", "target_ms": 1.0}}, 16, 16)
    renderer.frame_quality = overload.FrameQuality()
    first = renderer.render(scene)
    for _ in range(overload.WARMUP_FRAMES + overload.DOWN_FRAMES + 1):
        result = renderer.render(scene)
    # A 1 ms target cannot be met: the controller stepped down from medium at scale 1
    # to the cheapest point, and says the target is not met.
    assert first.overload["scale"] == 1.0 and first.overload["rungs"]["volumes"] == "medium"
    assert result.overload["scale"] == 0.5 and result.overload["met"] is False
    assert renderer.frame_quality.controller.index == 0


def test_preset_and_target_in_the_scene_model():
    assert Scene.model_validate({"quality": {"preset": "auto", "target_ms": 33.3}}).quality.preset == "auto"
    assert Scene.model_validate({"quality": {"target_fps": 25}}).quality.target_fps == 25.0
    assert Scene().quality.target_fps == 0.0  # off by default
    for bad in ({"preset": "ultra"}, {"target_ms": 0.0}, {"target_ms": float("nan")}, {"target_ms": "fast"},
                {"target_fps": 4.0}, {"target_fps": 241.0}, {"target_fps": -1.0}, {"target_fps": float("nan")}):
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


def test_service_bench_starts_its_server_with_the_preset():
    """``igserver bench --service --preset auto``: the server it starts runs the scene at that preset (the
    README's stream table holds targets with the auto preset); the choices are the scene model's."""
    from igserver.cli import PRESET_CHOICES
    from igserver.protocol.bench import server_command
    from igserver.scene.model import PRESET_NAMES

    command = server_command(640, 360, "demo", 8123, "auto")
    assert command[command.index("--preset") + 1] == "auto" and command[command.index("--scene") + 1] == "demo"
    assert "--preset" not in server_command(640, 360, None, 8123)
    # --no-rehearse reaches the server it starts (the fire bench's comparison), rehearsing by default
    assert "--no-rehearse" in server_command(640, 360, None, 8123, rehearse=False)
    assert "--no-rehearse" not in command
    assert tuple(PRESET_CHOICES) == PRESET_NAMES == ("low", "medium", "high", "auto")


def test_the_ladder_does_not_depend_on_the_order_pipelines_registered_in():
    """A process that imports the volumes before the sea gets the same rungs (and so the same operating
    points) as one that imports them the other way round."""
    import igserver.render.precip.particles  # noqa: F401 - registers the precipitation knobs
    import igserver.render.water.water  # noqa: F401 - registers the water knobs

    before = [r.name for r in presets.ladder()]
    first = next(iter(presets.registered()))
    per_level = presets.registered()[first]
    presets._KNOBS.pop(first)
    presets.register(first, per_level)  # registered last this time
    assert [r.name for r in presets.ladder()] == before
