"""Host work the passes keep between frames (each item keyed on all of its inputs, recomputations
counted) and the exposure meter's shortcuts, which must give the values of the plain computation
bit for bit: frames stay identical."""

import numpy as np
import pytest

from igserver.render import shaders
from igserver.render.post import exposure
from igserver.render.renderer import Renderer
from igserver.render.sky import sky
from igserver.render.volumes import volumes
from igserver.scene import apply_patch, load_scene


@pytest.fixture(scope="module")
def renderer():
    r = Renderer()
    yield r
    r.release()


def _demo(width=64, height=36, **camera):
    return apply_patch(load_scene("demo"), {"camera": {"width": width, "height": height, **camera}})


def _stream(renderer, scene, frames, t0=None):
    t0 = scene.time.sim_time if t0 is None else t0
    for i in range(frames):
        renderer.render(apply_patch(scene, {"time": {"sim_time": t0 + i / 30.0}}))


def test_frame_graph_and_volumes_pass_share_the_visible_volumes(renderer, monkeypatch):
    # The frame graph asks the volumes pass whether it is needed before it draws: both read one
    # memo item, so a stream finds the visible volumes never, a turned camera once.
    calls = []
    real = volumes.visible_volumes
    monkeypatch.setattr(volumes, "visible_volumes", lambda scene, view: calls.append(1) or real(scene, view))
    scene = _demo()
    _stream(renderer, scene, 2)
    calls.clear()
    _stream(renderer, scene, 4, t0=scene.time.sim_time + 1.0)
    assert calls == []
    _stream(renderer, _demo(heading=291.0), 1)
    assert len(calls) == 1


def test_cirrus_polygon_and_drift_bound_found_once_per_view(renderer):
    # 640 px wide: the cirrus table (not the per-pixel layer) is drawn, from its polygon.
    scene = _demo(640, 360)
    _stream(renderer, scene, 2)
    poly, ray = sky._cirrus_polygon.cache_info().misses, sky._highest_ray_z.cache_info().misses
    _stream(renderer, scene, 3, t0=scene.time.sim_time + 1.0)
    assert (sky._cirrus_polygon.cache_info().misses, sky._highest_ray_z.cache_info().misses) == (poly, ray)
    _stream(renderer, _demo(640, 360, heading=291.0), 3)  # (the drift is bounded from its second frame)
    assert sky._cirrus_polygon.cache_info().misses == poly + 1
    assert sky._highest_ray_z.cache_info().misses == ray + 1


def test_kept_cirrus_polygon_is_the_computed_one():
    args = (np.eye(3)[:, [0, 2, 1]].copy().tobytes(), (-0.8, 0.8, -0.45, 0.45), 6360.0, 6.0, 8.0, (320, 180))
    kept = sky._cirrus_polygon(*args)
    np.testing.assert_array_equal(kept, sky._cirrus_polygon.__wrapped__(*args))
    assert not kept.flags.writeable  # shared between frames


@pytest.mark.parametrize("hot", [0, 1, 2, 8, 9, 40])
def test_meter_moves_few_hot_cells_one_by_one_to_the_same_root(monkeypatch, hot):
    # Cells past the path to white are moved in Python floats when few: the same operations in the
    # same order as the numpy path, so the same EV100 to the last bit.
    rng = np.random.default_rng(hot)
    cells = rng.uniform(0.0, 300.0, (576, 3))
    cells[:hot] *= rng.uniform(30.0, 3000.0, (hot, 1))  # sun-lit cloud edges, the sun's disk
    fast = exposure.display_metered_ev100(cells)
    monkeypatch.setattr(exposure, "FEW_HOT_CELLS", -1)
    assert fast == exposure.display_metered_ev100(cells)


def test_uniform_key_of_a_vector_is_the_vector_and_arrays_are_frozen():
    assert shaders._frozen((1.0, 2.0, 3.0)) == (1.0, 2.0, 3.0)
    a = np.arange(3, dtype=np.float32)
    assert shaders._frozen((a, 1.0)) == (shaders._frozen(a), 1.0)
    assert shaders._frozen([1.0, [2.0]]) == (1.0, (2.0,))
    hash(shaders._frozen((a, [1.0])))


def _frame_like(**changes) -> dict:
    """A dict of many values, as the frame's are, most of them not the program's."""
    values = {f"u_unused_{i}": float(i) for i in range(60)}
    return {**values, "u_hdr": 0, "u_exposure_correction": 1.5, "u_rod_fraction": 0.25, **changes}


def test_an_array_changed_in_place_is_written_though_the_dict_is_the_same(renderer):
    program = shaders.ProgramCache(renderer.ctx).program("common/fullscreen.vert.glsl", "post/tonemap.glsl", {"MESOPIC": 1, "HALOS": 1})
    value = np.array(1.5, dtype=np.float32)
    values = _frame_like(u_exposure_correction=value)
    shaders.set_uniforms(program, values)
    value[...] = 2.5  # the same object, new content
    shaders.set_uniforms(program, values)
    assert program["u_exposure_correction"].value == pytest.approx(2.5)


def test_fog_layer_key_found_once_and_a_settled_stream_keeps_one_eased_layer(renderer):
    from igserver.render.sky import frame_sky
    from igserver.render.sky.haze import HazeLayer
    layer = HazeLayer(np.array([1e-4, 2e-4, 3e-4]), 10.0, 100.0, 0.8, 0.9)
    assert not layer.beta.flags.writeable  # its own copy: the key cannot go stale
    assert layer.key is layer.key
    scene = _demo()
    _stream(renderer, scene, 3)
    before = frame_sky.SKY_PARTS.computed["eased_haze"]
    _stream(renderer, scene, 4, t0=scene.time.sim_time + 0.1)
    assert frame_sky.SKY_PARTS.computed["eased_haze"] == before
    _stream(renderer, apply_patch(scene, {"atmosphere": {"visibility": 9000.0}}), 1)
    assert frame_sky.SKY_PARTS.computed["eased_haze"] == before + 1


def test_each_frame_gets_its_own_copy_of_the_operating_point_report(renderer):
    scene = _demo()
    a = renderer.render(scene).overload
    decision = renderer.frame_quality.decide(scene, renderer.render_scale)
    assert a == decision.fields()
    a["rungs"]["water"] = "changed"
    a["scale"] = -1.0
    assert renderer.render(scene).overload == decision.fields()


def test_lights_ranked_as_numpy_ranks_them():
    from igserver.render import lights
    from igserver.render.camera import make_view
    from igserver.render.point_lights import PointLight
    scene = _demo()
    view = make_view(scene.camera)
    rng = np.random.default_rng(3)
    made = [PointLight(view.position + rng.normal(0.0, 40.0, 3) + np.array([0.0, 60.0, 0.0]),
                       rng.uniform(0.0, 500.0, 3) * (i % 7 != 0), 200.0) for i in range(40)]
    made += [PointLight(made[1].position.copy(), made[1].color.copy(), 200.0)]  # a tie keeps its order

    def importance(light):
        d = float(np.linalg.norm(view.relative(light.position)))
        return float(np.max(light.color)) / max(d * d, 1.0)

    def reference():
        kept = [l for l in made if float(np.max(l.color)) > 0.0 and view.sphere_visible(l.position, l.range)]
        return sorted(kept, key=importance, reverse=True)[:24]

    saved = lights.LIGHT_SOURCES
    try:
        lights.LIGHT_SOURCES = [lambda scene: made]
        got = lights.gather_lights(scene, view, 24)
    finally:
        lights.LIGHT_SOURCES = saved
    assert [id(l) for l in got] == [id(l) for l in reference()]


def test_aerial_table_tests_a_still_view_once(renderer, monkeypatch):
    from igserver.render.common import aerial_table
    calls = []
    real = aerial_table.view_inside
    monkeypatch.setattr(aerial_table, "view_inside", lambda *a, **k: calls.append(1) or real(*a, **k))
    scene = _demo(640, 360)  # the table serves frames of at least its node count
    _stream(renderer, scene, 2)
    calls.clear()
    _stream(renderer, scene, 3, t0=scene.time.sim_time + 1.0)
    assert calls == []
    _stream(renderer, _demo(640, 360, heading=289.0), 1)
    assert calls
