"""Screen-tile light lists (render/light_tiles.py, common/lights.glsl LIGHT_TILES): a pixel loops over
the lights that can reach its tile only. A light adds exactly 0 beyond its range (range_window), so
leaving it out of a tile it cannot reach must change no pixel: the frames are compared bit for bit
(the HDR target, float16) with the full loop, and the host's lists against a brute-force test of points
seen in each tile."""

from __future__ import annotations

import numpy as np
import pytest

from helpers import forcing_defines

from igserver.render import light_tiles
from igserver.render.camera import make_view
from igserver.render.frame import _view_uniforms
from igserver.render.frame_block import MAX_LIGHTS
from igserver.render.light_tiles import LIGHT_TILE_PX, LightTiles, tile_grid, tile_masks
from igserver.scene import apply_patch, load_scene
from igserver.scene.model import Scene

SMALL = {"camera": {"width": 160, "height": 90}}


@pytest.fixture
def fresh_lists(renderer):
    """The context's tile lists dropped before and after the test (a forced list stays out of the
    other tests' frames)."""
    LightTiles.get(renderer.ctx).release()
    yield
    LightTiles.get(renderer.ctx).release()


def _always_tiled(monkeypatch, renderer):
    """Tile lists for every view, even where each tile would list every light (the camera inside every
    light's range): the lookup then runs and must leave every light in."""
    LightTiles.get(renderer.ctx).release()  # the lists kept for the frame before: none for this view
    monkeypatch.setattr(light_tiles, "camera_in_every_range", lambda centres, ranges: False)
    monkeypatch.setattr(light_tiles, "tile_lists",
                        lambda right, up, forward, tangents, width, height, centres, ranges: tile_masks(
                            right, up, forward, tangents, width, height,
                            np.column_stack([np.asarray(centres, np.float64), ranges]), len(centres)))


def _hdr(renderer, scene) -> np.ndarray:
    renderer.render(scene)  # the frame before: particles and eye adaptation settled at this instant
    renderer.render(scene)
    return renderer.read_hdr()


def _lamps(n_side: int = 4, light_range: float = 14.0, intensity: float = 800.0) -> Scene:
    """Night ground under a grid of lamps whose range reaches part of the view each (a street, a yard)."""
    lights = [{"id": f"lamp{i}{j}", "type": "point", "position": [-18.0 + 12.0 * i + 1.5 * j, 10.0 * j, 5.0],
               "color": [1.0, 0.8, 0.55], "intensity": intensity, "range": light_range}
              for j in range(n_side) for i in range(n_side)]
    return Scene.model_validate({
        "camera": {"position": [0.0, -40.0, 6.0], "heading": 0.0, "pitch": 2.0, "fov_y": 55.0,
                   "width": 320, "height": 180, "exposure_ev": 4.0},
        "time": {"utc": "2026-09-15T21:00:00Z", "sim_time": 100.0},
        "location": {"lat": 59.93, "lon": 30.31},
        "ground": {"enabled": True, "level": 0.0, "color": [0.2, 0.19, 0.17]},
        "lights": lights})


@pytest.mark.parametrize("name", ["night_fire_16", "sea_harbour_fire", "rain_harbour"])
def test_tile_lists_change_no_pixel_where_every_light_reaches_everywhere(renderer, monkeypatch, fresh_lists, name):
    # night_fire_16's twelve fire lights reach 240-1900 m and the camera stands inside all of them, so
    # the frame keeps the plain loop; sea_harbour_fire adds the sea (water.frag.glsl) and a spot light,
    # rain_harbour the rain (its compute pass includes the lights with the lists declared). With lists forced on, every pixel reads its tile's list and must
    # find every light in it: the same HDR frame, bit for bit.
    scene = apply_patch(load_scene(name), SMALL)
    plain = _hdr(renderer, scene)
    _always_tiled(monkeypatch, renderer)
    builds = LightTiles.get(renderer.ctx).builds
    forced = _hdr(renderer, scene)
    assert LightTiles.get(renderer.ctx).builds > builds  # the lists were made and read
    assert np.array_equal(forced, plain)


def test_lamps_frame_is_tiled_and_the_same_as_the_full_loop(renderer, monkeypatch):
    scene = _lamps()
    view = make_view(scene.camera)
    u = _view_uniforms(view, scene.camera)
    renderer.render(scene)
    lists = LightTiles.get(renderer.ctx)
    key = next(reversed(lists._lists))
    assert lists._lists[key] is not None, "lamps of 14 m seen from 40 m: the frame should be tiled"
    pos = np.array([np.append(view.relative(lt.position), lt.range) for lt in scene.lights])
    masks = tile_masks(u["u_camera_right"], u["u_camera_up"], u["u_camera_forward"], u["u_frustum_tangents"],
                       scene.camera.width, scene.camera.height, pos, len(pos))
    per_tile = np.unpackbits(masks.view(np.uint8), axis=-1).sum(axis=-1)
    assert per_tile.mean() < 0.5 * len(pos)  # the point of the lists: most tiles see few lamps
    tiled = _hdr(renderer, scene)
    forcing_defines(monkeypatch, LIGHT_TILES=0)
    assert np.array_equal(_hdr(renderer, scene), tiled)


def test_a_light_that_reaches_part_of_the_view_lights_exactly_that_part(renderer):
    # One lamp of 6 m range 30 m in front of the camera, off to the right: ground points beyond 6 m of
    # it must be exactly as without the lamp (its window is 0 there), those well within it brighter —
    # also in the tiles whose lists hold it, which are only part of the screen.
    lamp = {"id": "lamp", "type": "point", "position": [8.0, -10.0, 3.0], "color": [1.0, 1.0, 1.0],
            "intensity": 500.0, "range": 6.0}
    base = _lamps()
    dark = base.model_copy(update={"lights": []})
    lit = Scene.model_validate({**base.model_dump(), "lights": [lamp]})
    without = _hdr(renderer, dark)
    with_lamp = _hdr(renderer, lit)
    lists = LightTiles.get(renderer.ctx)
    texture = lists._lists[next(reversed(lists._lists))]
    assert texture is not None
    tiles = np.frombuffer(texture.read(), np.uint32).reshape(texture.size[1], texture.size[0], 2)
    assert 0 < np.count_nonzero(tiles[..., 0]) < tiles[..., 0].size  # the lamp listed in part of the tiles
    world = make_view(lit.camera).pixel_world(renderer.read_distance(), far=1e4)
    d = np.linalg.norm(world - np.array(lamp["position"]), axis=-1)
    beyond = d > 6.0 * 1.0001
    within = d < 0.8 * 6.0
    assert beyond.sum() > 1000 and within.sum() > 100
    assert np.array_equal(with_lamp[beyond], without[beyond])
    lum = lambda hdr: hdr[..., :3] @ np.array([0.2126, 0.7152, 0.0722])
    assert np.all(lum(with_lamp)[within] > lum(without)[within] * 1.05)


def test_every_light_that_reaches_a_point_is_in_its_tile():
    # Brute force: random lights around a tilted, asymmetric view, random points along random pixel
    # rays; a light whose sphere holds the point must be in the list of the tile the point is seen in.
    rng = np.random.default_rng(7)
    scene = apply_patch(load_scene("night_fire_16"), {"camera": {"width": 333, "height": 171, "roll": 7.0, "pitch": -9.0}})
    view = make_view(scene.camera)
    u = _view_uniforms(view, scene.camera)
    n = MAX_LIGHTS
    centres = rng.uniform(-60.0, 60.0, (n, 3)) + 40.0 * view.forward
    ranges = rng.uniform(2.0, 25.0, n)
    masks = tile_masks(u["u_camera_right"], u["u_camera_up"], u["u_camera_forward"], u["u_frustum_tangents"],
                       view.width, view.height, np.column_stack([centres, ranges]), n)
    assert masks.shape[:2] == tile_grid(view.width, view.height)[::-1]
    rays = view.pixel_rays()  # top row first
    rows, cols = rng.integers(0, view.height, 20000), rng.integers(0, view.width, 20000)
    points = rays[rows, cols] * rng.uniform(0.5, 150.0, 20000)[:, None]
    reach = np.sum((points[:, None, :] - centres[None]) ** 2, axis=-1) < ranges ** 2  # (points, lights)
    tile_rows = (view.height - 1 - rows) // LIGHT_TILE_PX  # texture row 0 at the bottom
    bits = masks[tile_rows, cols // LIGHT_TILE_PX]  # (points, 2)
    listed = ((bits[:, :1] >> np.arange(32, dtype=np.uint32)) & 1).astype(bool)
    listed = np.concatenate([listed, ((bits[:, 1:] >> np.arange(32, dtype=np.uint32)) & 1).astype(bool)], axis=1)
    assert reach.sum() > 1000
    assert not np.any(reach & ~listed)
    assert listed.sum() < 0.5 * listed.size  # and the lists do leave lights out


def test_a_flickering_range_does_not_rebuild_the_lists(renderer):
    # A fire's range follows its flickering intensity; the lists are built for ranges rounded up to a
    # quarter octave, so a few per cent of flicker finds the lists of the frame before.
    scene = _lamps()
    renderer.render(scene)
    lists = LightTiles.get(renderer.ctx)
    builds = lists.builds
    for gain in (1.01, 0.99, 1.02):
        flicker = [lt.model_copy(update={"range": lt.range * gain}) for lt in scene.lights]
        renderer.render(scene.model_copy(update={"lights": flicker}))
    assert lists.builds == builds


def test_channels_each_read_their_own_lists(renderer, monkeypatch):
    # Two channels turned 25 deg left and right (render/multiview.py): each view has its lists, bound
    # with its frame block; a channel that read the other's would drop lamps it can see.
    scene = apply_patch(_lamps(), {"channels": [dict(id="l", heading=-25.0, width=160, height=90),
                                                dict(id="r", heading=25.0, width=160, height=90)]})
    renderer.render(scene)
    tiled = {cid: part.rgba for cid, part in renderer.render(scene).channels.items()}
    forcing_defines(monkeypatch, LIGHT_TILES=0)
    renderer.render(scene)
    plain = {cid: part.rgba for cid, part in renderer.render(scene).channels.items()}
    assert all(np.array_equal(tiled[cid], plain[cid]) for cid in ("l", "r"))
