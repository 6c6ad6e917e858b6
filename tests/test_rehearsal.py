"""The rehearsal (render/rehearsal.py): the programs a host's usual changes need are compiled before the
host makes them, and the stream it ran beside is unchanged by it. Fresh renderers: the session's shared
one has compiled everything other tests drew, so a program it lacks would prove nothing."""

from __future__ import annotations

import numpy as np
import pytest

from helpers import tiny
from igserver.render.gl_count import GLCallCounter
from igserver.render.operating_points import SCALES
from igserver.render.rehearsal import SEA_WINDS, rehearsals
from igserver.render.renderer import Renderer
from igserver.scene import apply_patch

SEA = tiny({"ocean": {"enabled": True}, "camera": {"position": [0, -40, 12], "pitch": -8.0},
            "atmosphere": {"model": "gradient", "visibility": 3000.0}, "time": {"sim_time": 10.0}})
FIRE = {"id": "f", "type": "fire", "position": [0, 60, 0], "diameter": 2.0}
# What a host does to a running exercise, one change at a time.
CHANGES = {
    "a fire": {"effects": [FIRE]},
    "a smoking fire": {"effects": [{**FIRE, "emits_smoke": True}]},
    "smoke": {"effects": [{**FIRE, "type": "smoke"}]},
    "a gas burner": {"effects": [{**FIRE, "type": "gas_burner"}]},
    "a lamp": {"lights": [{"id": "l", "position": [0, 20, 3], "range": 30.0}]},
    "a searchlight": {"lights": [{"id": "s", "type": "spot", "position": [0, 20, 3], "range": 30.0, "pitch": -20}]},
    "lamps lighting patches": {"lights": [{"id": f"l{i}", "position": [8.0 * i - 12, 15, 1], "range": 5.0}
                                          for i in range(4)]},
    "a lamp and a spot lighting patches": {"lights": [
        {"id": "l", "position": [8, 15, 1], "range": 5.0},
        {"id": "s", "type": "spot", "position": [-8, 15, 1], "range": 5.0, "pitch": -20}]},
    "rain": {"weather": {"precipitation": {"type": "rain", "rate": 3.0}}},
    "snow": {"weather": {"precipitation": {"type": "snow", "rate": 2.0}}},
    "a rising wind": {"weather": {"wind_speed": 15.0}},
    "a calm": {"weather": {"wind_speed": 1.5}},
    "the eye under water": {"camera": {"position": [0, -40, -2]}},
}


@pytest.fixture(scope="module")
def fresh():
    """A renderer that has drawn the sea scene only, then rehearsed it; and one that has not rehearsed."""
    rehearsed, bare = Renderer(), Renderer()
    for r in (rehearsed, bare):
        r.render(SEA)
    done = rehearsed.rehearse(SEA)
    yield rehearsed, bare, done
    rehearsed.release()
    bare.release()


def test_the_rehearsal_draws_a_fire_lights_rain_and_snow_beside_the_scene():
    scenes = rehearsals(SEA)
    assert any(s.effects and s.effects[-1].type == "fire" and s.effects[-1].emits_smoke for s in scenes)
    assert {e.type for s in scenes for e in s.effects} == {"fire", "smoke", "gas_burner"}
    assert {light.type for s in scenes for light in s.lights} == {"point", "spot"}
    assert {s.weather.precipitation.type for s in scenes} >= {"rain", "snow"}
    assert all(not s.channels and s.quality.target_fps == 0 for s in scenes)
    # with a sea: a rough one, a calm one, the eye under its surface; without, none of them
    assert {s.weather.wind_speed for s in scenes} >= {2.0, 28.0}
    assert any(s.camera.position[2] < SEA.ocean.level for s in scenes)
    dry = rehearsals(apply_patch(SEA, {"ocean": {"enabled": False}}))
    assert len(dry) == len(scenes) - len(SEA_WINDS) - 1 and all(s.camera == SEA.camera for s in dry)
    # a scene already at the model's limit of effects gets no more (nor a light past the frame block's)
    full = apply_patch(SEA, {"effects": [{**FIRE, "id": f"e{i}"} for i in range(64)]})
    assert all(len(s.effects) == 64 for s in rehearsals(full))


@pytest.mark.parametrize("change", list(CHANGES))
def test_a_change_after_the_rehearsal_compiles_no_program(fresh, change):
    rehearsed, _, done = fresh
    assert done["scenes"] == 7 + len(SEA_WINDS) and done["programs"] > 0
    before = len(rehearsed.programs)
    rehearsed.render(apply_patch(SEA, {**CHANGES[change], "time": {"sim_time": 10.5}}))
    assert len(rehearsed.programs) == before, f"{change}: compiled after the rehearsal"


def test_a_wind_sweeping_from_a_calm_to_a_storm_compiles_no_program_after_the_rehearsal(fresh):
    """The sea's programs follow its state (detail maps resolved, foam, its dots and wind rows): every
    wind a host may send meets programs the rehearsal's few winds compiled."""
    rehearsed, _, _ = fresh
    before = len(rehearsed.programs)
    for i, wind in enumerate((0.5, 1.0, 2.5, 3.0, 3.5, 4.0, 5.0, 6.0, 8.0, 10.0, 12.0, 16.0, 20.0, 26.0, 32.0)):
        rehearsed.render(apply_patch(SEA, {"weather": {"wind_speed": wind}, "time": {"sim_time": 11.0 + i / 30}}))
        assert len(rehearsed.programs) == before, f"{wind} m/s: compiled after the rehearsal"


def test_the_rehearsal_reports_each_scene_it_drew(fresh):
    rehearsed, _, _ = fresh
    calls = []
    done = rehearsed.rehearse(SEA, lambda drawn, total: calls.append((drawn, total)))
    assert calls == [(i, done["scenes"]) for i in range(1, done["scenes"] + 1)]


def test_without_a_rehearsal_a_first_fire_compiles(fresh):
    """What the rehearsal is for: the same first change on a renderer that did not rehearse."""
    _, bare, done = fresh
    before = len(bare.programs)
    bare.render(apply_patch(SEA, {**CHANGES["a smoking fire"], "time": {"sim_time": 10.5}}))
    assert len(bare.programs) - before >= 4  # the volumes' programs at least, and the lit variants


@pytest.mark.parametrize("channels", [False, True], ids=["camera", "two channels"])
def test_the_stream_beside_a_rehearsal_is_unchanged(channels):
    """The same stream with and without a rehearsal between its frames: bit-identical frames (its eye
    adaptation, eased fog and meter cells carried on, not taken from the rehearsal's fire; a channel's
    targets, meter and per-view state kept)."""
    night = apply_patch(SEA, {"time": {"sun_override": {"elevation": -8.0, "azimuth": 270.0}}, "effects": [FIRE]})
    if channels:
        night = apply_patch(night, {"channels": [dict(id=cid, heading=h, width=48, height=36)
                                                 for cid, h in (("port", -30.0), ("ahead", 0.0))]})
    frames = {}
    for rehearse in (False, True):
        r = Renderer()
        try:
            out = [r.render(apply_patch(night, {"time": {"sim_time": 10.0 + i / 30}})).rgba for i in range(2)]
            if rehearse:
                count = r.frames_rendered
                r.rehearse(apply_patch(night, {"time": {"sim_time": 10.0 + 1 / 30}}))
                assert r.frames_rendered == count
            with GLCallCounter() as calls:  # nothing of the stream's was dropped and made again
                out.append(r.render(apply_patch(night, {"time": {"sim_time": 10.0 + 2 / 30}})).rgba)
            assert calls.created() == 0, calls.by_name
            out += [r.render(apply_patch(night, {"time": {"sim_time": 10.0 + i / 30}})).rgba for i in range(3, 5)]
            frames[rehearse] = out
        finally:
            r.release()
    for i, (a, b) in enumerate(zip(frames[False], frames[True])):
        assert np.array_equal(a, b), f"frame {i} differs after a rehearsal"


def test_a_held_streams_rehearsal_keeps_its_targets_and_scale():
    """A scene that holds a frame rate is rehearsed at the full size and at the controller's smallest
    scale too (render/overload.py SCALES), in targets of its own: the stream's targets, upscaler and
    scale are the ones it had, none of them released."""
    import moderngl

    held = apply_patch(SEA, {"quality": {"target_fps": 25.0}})
    r = Renderer()
    try:
        r.render_scale = 0.75
        r.render(apply_patch(held, {"quality": {"target_fps": 0.0}}))  # drawn at 0.75: targets and upscaler
        targets, upscaler = r._targets, r._upscaler
        assert targets is not None and upscaler is not None
        done = r.rehearse(held)
        assert done["scenes"] == 2 * len(rehearsals(held)) + 3 * len(SCALES)  # + each preset at each scale
        assert (r._targets, r._upscaler, r.render_scale) == (targets, upscaler, 0.75)
        alive = (targets.hdr, targets.scene_fbo, targets.ldr_fbo, upscaler._out.texture)
        assert not any(isinstance(o.mglo, moderngl.mgl.InvalidObject) for o in alive)
    finally:
        r.release()


def test_a_held_stream_meets_no_compile_at_any_point_its_controller_may_choose():
    """The overload controller steps to smaller scales and lower rungs exactly when the machine is
    short of time: after the rehearsal, drawing the held scene at every point of its frontier
    compiles nothing."""
    held = apply_patch(SEA, {"quality": {"target_fps": 25.0, "preset": "auto"}})
    r = Renderer()
    try:
        r.render(held)
        points = list(r.frame_quality.controller.points)
        assert {p.scale for p in points} == set(SCALES) and len({p.rung.name for p in points}) > 3
        r.rehearse(held)
        before = len(r.programs)
        controller_point = r.quality_for
        for i, point in enumerate(points):  # the controller's decision, drawn at this point instead
            r.quality_for = lambda scene, p=point: (p.rung, p.scale, controller_point(scene)[2])
            r.render(apply_patch(held, {"time": {"sim_time": 10.0 + i / 30}}))
            assert len(r.programs) == before, f"scale {point.scale}, {point.rung.name}: compiled after the rehearsal"
    finally:
        r.release()


def test_the_render_process_rehearses_on_request():
    from igserver.render.worker import RenderService

    import threading
    import time

    with RenderService() as service:
        first = service.render(SEA)
        seen, stop = [], threading.Event()

        def watch():  # the render process's progress messages, as /v1/ready shows them
            while not stop.is_set():
                seen.append(service.progress)
                time.sleep(0.002)

        watcher = threading.Thread(target=watch)
        watcher.start()
        try:
            done = service.rehearse(SEA)
        finally:
            stop.set()
            watcher.join()
        phases = {p["phase"] for p in seen if p}
        assert phases == {"compiling ahead"} and service.progress is None
        assert done["scenes"] == 7 + len(SEA_WINDS) and done["programs"] > 0 and done["seconds"] > 0
        assert service.ig_frame == first.ig_frame  # no frame came back for it
        after = service.render(apply_patch(SEA, {**CHANGES["a smoking fire"], "time": {"sim_time": 10.5}}))
        assert after.ig_frame == first.ig_frame + 1
