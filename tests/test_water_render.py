"""The water pass on the GPU: watertight LOD, the mesh equals the host query, hulls keep the sea out,
calm and storm pictures, long-time stability. Tiny frames, the session renderer."""

from __future__ import annotations

import numpy as np
import pytest

from igserver.photometry import LUMA
from igserver.render.camera import make_view
from igserver.render.graph import plan_passes
from igserver.render.water import lod
from igserver.scene import apply_patch
from igserver.scene.model import Scene, Weather
from igserver.water import sea_surface

from helpers import with_and_without_skip

EARTH_RADIUS = 6.371e6


def sea_scene(**patch) -> Scene:
    base = {"camera": {"position": [0.0, 0.0, 12.0], "heading": 30.0, "pitch": -8.0, "fov_y": 60.0,
                       "width": 96, "height": 54},
            "time": {"utc": "2026-06-21T09:00:00Z", "sim_time": 100.0}, "location": {"lat": 43.0, "lon": 5.0},
            "weather": {"wind_speed": 10.0, "wind_direction": 240.0}, "ocean": {"enabled": True}}
    return apply_patch(Scene(), _merge(base, patch))


def _merge(a: dict, b: dict) -> dict:
    out = dict(a)
    for k, v in b.items():
        out[k] = _merge(a[k], v) if isinstance(v, dict) and isinstance(a.get(k), dict) else v
    return out


def luminance(rgb: np.ndarray) -> np.ndarray:
    return rgb[..., :3].astype(np.float64) @ LUMA / 255.0


def test_scenes_without_ocean_skip_the_water_pass():
    assert "water" not in plan_passes(Scene())
    assert "water" in plan_passes(sea_scene())


SIDE_BITS = {"bottom": 1, "right": 2, "top": 4, "left": 8}  # lod.SIDES


def _edge(positions: np.ndarray, node: np.ndarray, side: str, coarse: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Rest coordinates along a block side and the displaced vertices drawn there (its two corners
    only where the side is one segment: ``coarse``, lod.SIDES bits)."""
    x0, y0, size = node[:3]
    g = lod.PATCH_QUADS
    t = np.arange(g + 1) / g * size
    if side == "left":
        rest, verts = np.column_stack([np.full(g + 1, x0), y0 + t]), positions[0, :, :]
    elif side == "right":
        rest, verts = np.column_stack([np.full(g + 1, x0 + size), y0 + t]), positions[g, :, :]
    elif side == "bottom":
        rest, verts = np.column_stack([x0 + t, np.full(g + 1, y0)]), positions[:, 0, :]
    else:
        rest, verts = np.column_stack([x0 + t, np.full(g + 1, y0 + size)]), positions[:, g, :]
    drawn = [0, g] if coarse & SIDE_BITS[side] else slice(None)
    return rest[drawn], verts[drawn]


def _distance_to_polyline(points: np.ndarray, line: np.ndarray) -> np.ndarray:
    a, b = line[:-1][None], line[1:][None]
    p = points[:, None]
    ab = b - a
    t = np.clip(np.sum((p - a) * ab, axis=-1) / np.maximum(np.sum(ab * ab, axis=-1), 1e-12), 0.0, 1.0)
    return np.min(np.linalg.norm(p - (a + t[..., None] * ab), axis=-1), axis=1)


@pytest.mark.parametrize("height,wind,mesh", [(2.0, 12.0, "default"), (300.0, 20.0, "default"),
                                              (2.0, 12.0, "coarse"), (300.0, 20.0, "coarse"),
                                              (1000.0, 10.0, "default")])
def test_lod_joins_are_watertight(renderer, height, wind, mesh):
    # Each block side as drawn (a flat side shared with a flat block of the same size: its corners
    # only) meets its neighbours' drawn sides: every drawn vertex lies on the other side's polyline.
    scene = sea_scene(camera={"position": [3.7, -8.2, height], "pitch": -20.0},
                      weather={"wind_speed": wind})
    selection, pos = renderer.graph.passes["water"].capture(scene, mesh)
    nodes = selection.nodes.astype(np.float64)
    coarse = selection.coarse_sides
    assert len(np.unique(nodes[:, 3])) >= 3  # several levels meet
    if height >= 1000.0:
        assert np.count_nonzero(coarse) > len(nodes) // 4  # the one-segment sides are checked too
    opposite = {"left": "right", "right": "left", "bottom": "top", "top": "bottom"}
    checked, worst = 0, 0.0
    for a, na in enumerate(nodes):
        for side in ("left", "right", "bottom", "top"):
            rest_a, verts_a = _edge(pos[a], na, side, int(coarse[a]))
            for b, nb in enumerate(nodes):
                if b == a:
                    continue
                rest_b, verts_b = _edge(pos[b], nb, opposite[side], int(coarse[b]))
                axis = 0 if side in ("left", "right") else 1
                if abs(rest_a[0, axis] - rest_b[0, axis]) > 1e-3:
                    continue
                other = 1 - axis
                lo = max(rest_a[0, other], rest_b[0, other])
                hi = min(rest_a[-1, other], rest_b[-1, other])
                if hi - lo <= 1e-3:
                    continue
                # Every vertex of A's border within the shared span lies on B's displaced border polyline.
                inside = (rest_a[:, other] >= lo - 1e-3) & (rest_a[:, other] <= hi + 1e-3)
                d = _distance_to_polyline(verts_a[inside].astype(np.float64), verts_b.astype(np.float64))
                worst = max(worst, float(d.max()))
                checked += 1
    assert checked > 20
    # float32 positions a few hundred metres from the camera round to ~3e-5 m; a crack is ≥ centimetres.
    assert worst < 5e-3


def test_height_query_equals_displaced_mesh(renderer):
    scene = sea_scene(camera={"position": [1234.5, -321.0, 6.0], "pitch": -30.0}, weather={"wind_speed": 14.0},
                      time={"sim_time": 12345.678})
    selection, pos = renderer.graph.passes["water"].capture(scene)
    finest = selection.nodes[:, 3] == 0
    verts = pos[finest].reshape(-1, 3).astype(np.float64)
    cam = np.asarray(scene.camera.position)
    r2 = np.sum(verts[:, :2] ** 2, axis=1)
    near = r2 < 150.0**2
    verts = verts[near]
    world_xy = verts[:, :2] + cam[:2]
    # The mesh is drawn on the curved earth relative to the camera; the query answers in flat ENU.
    mesh_z = verts[:, 2] + cam[2] + r2[near] / (2 * EARTH_RADIUS)
    sea = sea_surface(scene.ocean, scene.weather)
    q = sea.query(world_xy, scene.time.sim_time)
    assert len(verts) > 200
    assert np.max(np.abs(q["height"] + scene.ocean.level - mesh_z)) < 0.01  # the 1 cm


def _centre(rgba: np.ndarray) -> np.ndarray:
    h, w = rgba.shape[:2]
    return rgba[h // 3: 2 * h // 3, w // 3: 2 * w // 3, :3].astype(np.float64)


def test_no_water_inside_a_hull(renderer):
    # A closed box hull (the built-in box, base at its z) 4 m deep in the water, 8 m above it.
    ship = {"id": "ship", "model": "box", "position": [0.0, 0.0, -4.0], "scale": [30.0, 150.0, 12.0]}
    # Camera inside the hull above the waterline, looking down at its floor 4 m below the sea level.
    view = {"camera": {"position": [0.0, -20.0, 3.0], "pitch": -80.0, "fov_y": 50.0}, "entities": [ship],
            "weather": {"wind_speed": 18.0}}
    with_sea = renderer.render(sea_scene(**view)).rgba
    dry = renderer.render(sea_scene(**view, ocean={"enabled": False}, ground={"enabled": False})).rgba
    # Inside the hull the picture is the hull's floor with or without a sea (8 levels: JPEG-free, the
    # same surfaces pass draws both; only exposure metering could differ, and it does not see the sea).
    assert np.max(np.abs(_centre(with_sea) - _centre(dry))) <= 8
    # Outside the hull, the same camera does see water: seen from above (pitch -80) it fills the frame.
    outside = renderer.render(sea_scene(**{**view, "camera": {"position": [200.0, 0.0, 3.0], "pitch": -80.0,
                                                                "fov_y": 50.0}})).rgba
    assert np.mean(np.abs(_centre(outside) - _centre(dry))) > 10


def _sea_rows(rgba: np.ndarray) -> np.ndarray:
    return rgba[int(rgba.shape[0] * 0.7):, :, :3]


def _look(sun_azimuth: float, wind: float, renderer) -> np.ndarray:
    look = {"camera": {"position": [0.0, 0.0, 10.0], "heading": 90.0, "pitch": -10.0, "fov_y": 40.0,
                       "width": 128, "height": 72},
            "time": {"utc": "2026-06-21T09:00:00Z", "sun_override": {"elevation": 12.0, "azimuth": sun_azimuth}},
            "weather": {"wind_speed": wind}}
    rgba = renderer.render(sea_scene(**look)).rgba
    assert np.all(np.isfinite(rgba.astype(float)))
    return luminance(_sea_rows(rgba))


def test_calm_is_glassy_and_storm_is_rough(renderer):
    # Sun behind the camera: rows of the sea vary with the surface roughness only.
    calm, storm = _look(270.0, 0.0, renderer), _look(270.0, 40.0, renderer)
    row_std_calm = float(np.median(np.std(calm, axis=1)))
    row_std_storm = float(np.median(np.std(storm, axis=1)))
    # 40 m/s: 20 m seas with foam streaks; calm: capillary ripples only.
    assert row_std_storm > 3.0 * row_std_calm
    assert storm.mean() > calm.mean()  # foam whitens the storm sea


def test_calm_sea_is_not_a_perfect_mirror(renderer):
    # Sun ahead, 12° up: a perfect mirror would show a sun disk of 0.53° (about one 0.56° pixel here)
    # below the horizon; the glassy sea's capillary slopes (Cox–Munk σ² = 0.003) spread it into a
    # glitter column of many pixels.
    calm = _look(90.0, 0.0, renderer)
    bright = calm > 0.5 * calm.max()
    assert calm.max() > 0.5 and bright.sum() > 20


def test_long_time_looks_like_short_time_and_is_deterministic(renderer):
    stats = []
    for t in (100.0, 1e6, 1e9):
        img = renderer.render(sea_scene(time={"sim_time": t})).rgba
        again = renderer.render(sea_scene(time={"sim_time": t})).rgba
        assert np.array_equal(img, again)  # same state, same picture
        lum = luminance(_sea_rows(img))
        stats.append((lum.mean(), lum.std()))
    (m0, s0), *rest = stats
    for m, s in rest:
        # Different instants of the same sea: same statistics (a pixelated or frozen sea would not be).
        assert m == pytest.approx(m0, rel=0.15) and s == pytest.approx(s0, rel=0.35)


def test_quality_presets_reach_the_water_knobs(renderer):
    """low / medium / high scale the scene's detail-map resolution and LOD error bound (medium = the
    scene's own values); the wave count, which defines the sea the host queries describe, stays."""
    seen = {}
    for preset in ("low", "medium", "high"):
        renderer.render(sea_scene(quality={"preset": preset}, ocean={"detail_resolution": 128, "lod_error": 1.0}))
        seen[preset] = dict(renderer.graph.passes["water"].stats)
    assert [seen[p]["detail_resolution"] for p in ("low", "medium", "high")] == [64, 128, 256]
    assert [seen[p]["lod_error_px"] for p in ("low", "medium", "high")] == [2.0, 1.0, 0.5]
    assert seen["low"]["triangles"] < seen["medium"]["triangles"]  # the coarse ring rule
    assert {seen[p]["waves"] for p in seen} == {24}


def test_water_pass_leaves_the_frame_textures_alone(renderer, monkeypatch):
    """The sky above the horizon is the same with and without the water pass: it binds its own
    textures on units the frame's shared tables (haze 8, sky view 9-11, atmosphere 12-15) do not use.
    (Its third detail map once sat on unit 8, and the sky, drawn after the water, read wave slopes as
    fog light: a dark band above the horizon.) The sea stays in the scene and only its pass is left
    out: a sea under the haze lights it (the sky it mirrors, sky/haze_lobe.glsl haze_sky_lobe)."""
    hazy = {"atmosphere": {"visibility": 3000.0}, "camera": {"pitch": 10.0, "exposure_ev": 13.0}}
    with_sea = renderer.render(sea_scene(**hazy)).rgba
    monkeypatch.setattr(type(renderer.graph.passes["water"]), "needed", lambda self, scene, view: False)
    without = renderer.render(sea_scene(**hazy)).rgba
    sky_rows = slice(0, 54 // 2)  # pitch 10 deg, fov 60: the horizon is 10 deg (9 rows) below the middle
    # Exact: the sky pass shades these pixels from the same state either way (fixed exposure, the
    # same dither), so any difference is state left behind by the water pass.
    assert np.array_equal(with_sea[sky_rows], without[sky_rows])


def test_sea_tables_refill_when_the_sky_changes_not_when_the_view_turns(renderer):
    water = renderer.graph.passes["water"]
    renderer.render(sea_scene(camera={"heading": 10.0}))
    fills = water._tables.fills
    renderer.render(sea_scene(camera={"heading": 70.0}))  # the view turns: same sky, same sea level
    assert water._tables.fills == fills
    renderer.render(sea_scene(camera={"heading": 70.0}, atmosphere={"visibility": 2000.0}))  # fog comes in
    assert water._tables.fills == fills + 1
    renderer.render(sea_scene(camera={"heading": 70.0}, time={"utc": "2026-06-21T09:30:00Z"}))  # the sun moves
    assert water._tables.fills == fills + 2


def test_pier_piles_and_the_boat_keep_the_sea_out():
    """Each pile of the demo pier is its own hull box (the piles are one glTF node of many pieces): the
    sea stays out of every pile and shows between them; the moored boat's hull is kept beside 20 piles."""
    from igserver.render.camera import make_view
    from igserver.render.water.hulls import hull_boxes, model_hulls
    from igserver.scene import load_scene

    piles = model_hulls("pier")
    assert len(piles) == 20
    centres = np.array([c for c, _ in piles])
    halves = np.array([h for _, h in piles])
    assert np.all(halves[:, :2] < 1.0)  # one pile each (0.7 m square), not the pier's 60 m footprint
    # A point between two neighbouring piles lies in no box: the sea shows there.
    a, b = centres[0], centres[np.argmin(np.linalg.norm(centres[1:] - centres[0], axis=1)) + 1]
    mid = 0.5 * (a + b)
    assert not np.any(np.all(np.abs(mid - centres) < halves, axis=1))
    scene = load_scene("demo")
    boxes = hull_boxes(scene, make_view(scene.camera))
    expected = sum(len(model_hulls(e.model)) for e in scene.entities if e.visible)  # piles, hull, buoy, ...
    assert expected > len(piles) and len(boxes) == expected  # nothing dropped for the piles


def test_only_blocks_near_a_hull_pay_for_the_hull_test():
    # A 10 m x 4 m x 6 m hull box centred 50 m ahead: the fragment hull test (and its discard) is
    # needed only on blocks whose footprint comes within the margin of the box's footprint.
    from igserver.render.water.hulls import blocks_near_hulls
    box = np.diag([5.0, 2.0, 3.0, 1.0])
    box[:3, 3] = (50.0, 0.0, -1.0)
    nodes = np.array([[40.0, -8.0, 16.0, 0],     # contains the box
                      [56.0, -8.0, 16.0, 0],     # its edge at x = 56 is 1 m past the box's (55): within 2 m
                      [58.0, -8.0, 16.0, 0],     # 3 m from it: outside a 2 m margin
                      [-500.0, -500.0, 64.0, 2]],  # far away
                     dtype=np.float32)
    near = blocks_near_hulls(nodes, [np.linalg.inv(box)], margin=2.0)
    assert near.tolist() == [True, True, False, False]
    assert not blocks_near_hulls(nodes, [], margin=2.0).any()


def test_fan_patch_shares_the_full_patch_border():
    # A flat block's fan must meet its neighbours exactly where the full patch would: the same border
    # vertices and segments, the square covered once, every triangle counter-clockwise from above.
    g = lod.PATCH_QUADS
    grid = np.array([(a, b) for a in range(g + 1) for b in range(g + 1)], dtype=np.float64)

    def border_edges(indices):
        tris = indices.reshape(-1, 3)
        edges = {}
        for t in tris:
            for k in range(3):
                e = tuple(sorted((int(t[k]), int(t[(k + 1) % 3]))))
                edges[e] = edges.get(e, 0) + 1
        return {e for e, n in edges.items() if n == 1}  # used by one triangle only: the outline

    def signed_areas(indices):
        p = grid[indices.reshape(-1, 3)]
        a, b = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
        return 0.5 * (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])

    fan, full = lod.fan_indices(), lod.patch_indices()
    assert border_edges(fan) == border_edges(full) and len(border_edges(fan)) == 4 * g
    assert np.all(signed_areas(fan) > 0) and np.all(signed_areas(full) > 0)
    assert signed_areas(fan).sum() == pytest.approx(g * g) == signed_areas(full).sum()
    assert len(fan) // 3 == lod.FAN_TRIANGLES


def test_fan_patch_with_one_segment_sides():
    # Every side mask: a side in the mask is the single segment between its corners, every other side
    # keeps the full patch's G segments; the square is covered once, counter-clockwise from above.
    g = lod.PATCH_QUADS
    grid = np.array([(a, b) for a in range(g + 1) for b in range(g + 1)], dtype=np.float64)
    corner = {"bottom": (0, g * (g + 1)), "right": (g * (g + 1), g * (g + 1) + g),
              "top": (g, g * (g + 1) + g), "left": (0, g)}
    full_border = {tuple(sorted(e)) for e in _border_edges(lod.patch_indices())}
    for mask in range(16):
        fan = lod.fan_indices(mask)
        p = grid[fan.reshape(-1, 3)]
        a, b = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
        areas = 0.5 * (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
        assert np.all(areas > 0) and areas.sum() == pytest.approx(g * g)
        assert len(fan) // 3 == lod.fan_triangles(mask) == sum(1 if mask & bit else g for bit in SIDE_BITS.values())
        expected = set()
        for side, bit in SIDE_BITS.items():
            lo, hi = corner[side]
            on_side = {e for e in full_border if _on_side(grid, e, side, g)}
            expected |= {tuple(sorted((lo, hi)))} if mask & bit else on_side
        assert _border_edges(fan) == expected


def _border_edges(indices: np.ndarray) -> set:
    edges: dict = {}
    for t in indices.reshape(-1, 3):
        for k in range(3):
            e = tuple(sorted((int(t[k]), int(t[(k + 1) % 3]))))
            edges[e] = edges.get(e, 0) + 1
    return {e for e, n in edges.items() if n == 1}


def _on_side(grid: np.ndarray, edge: tuple, side: str, g: int) -> bool:
    p = grid[list(edge)]
    axis, value = {"bottom": (1, 0), "top": (1, g), "left": (0, 0), "right": (0, g)}[side]
    return bool(np.all(p[:, axis] == value))


def test_one_segment_sides_are_shared_whole_with_a_flat_block():
    # From 1 km most blocks are flat. A side is one segment exactly when a flat block of the same size
    # lies across it, and then that block's facing side is one segment too (the join has the same two
    # vertices on both sides); with the knob off every fan keeps its G segments a side.
    scene = sea_scene(camera={"position": [0.0, 0.0, 1000.0], "pitch": -20.0}, weather={"wind_speed": 10.0})
    view = make_view(scene.camera)
    sea = sea_surface(scene.ocean, scene.weather)
    args = (view, 1000.0, sea.waves.k, sea.waves.amplitude, scene.camera.fov_y, 1.0, view.far)
    selection = lod.select(*args)
    nodes = selection.nodes.astype(np.float64)
    flat, coarse = selection.flat, selection.coarse_sides
    where = {(n[2], round(n[0] / n[2]), round(n[1] / n[2])): i for i, n in enumerate(nodes)}
    opposite = {1: 4, 4: 1, 2: 8, 8: 2}
    for i, n in enumerate(nodes):
        for bit, (dx, dy) in lod.SIDES:
            j = where.get((n[2], round(n[0] / n[2]) + dx, round(n[1] / n[2]) + dy))
            shared = j is not None and flat[i] and flat[j]
            assert bool(coarse[i] & bit) == shared
            if shared:
                assert coarse[j] & opposite[bit]
    assert np.count_nonzero(coarse) > len(nodes) // 2
    plain = lod.select(*args, coarse_sides=False)
    assert not plain.coarse_sides.any() and np.array_equal(plain.nodes, selection.nodes)
    assert selection.triangles < 0.8 * plain.triangles


def test_fan_blocks_carry_no_wave(renderer):
    # From 1 km most blocks are fans; their level's spacing has faded every wave out, so the displaced
    # mesh there is exactly the mean sea sphere (a fan's interior loses nothing), while the level just
    # finer still carries waves (the first flat level is not later than it must be).
    scene = sea_scene(camera={"position": [0.0, 0.0, 1000.0], "pitch": -20.0}, weather={"wind_speed": 10.0})
    selection, pos = renderer.graph.passes["water"].capture(scene)
    level = selection.nodes[:, 3].astype(int)
    flat = selection.flat
    assert flat.sum() > len(flat) // 2 and (level == selection.flat_level - 1).any()
    p = pos.reshape(len(pos), -1, 3).astype(np.float64)
    r2 = np.sum(p[..., :2] ** 2, axis=-1)
    height = p[..., 2] + r2 / (EARTH_RADIUS + np.sqrt(EARTH_RADIUS**2 - r2)) - (scene.ocean.level - 1000.0)
    # The shader's float32: z is metres to kilometres (the drop at 160 km is 2 km), a few ulps of it.
    tol = 8.0 * float(np.spacing(np.float32(np.abs(p[flat][..., 2]).max())))
    assert np.max(np.abs(height[flat])) < tol
    # One level finer the longest wave is faded to ~1e-3 of its 0.1-0.2 m but not to 0: centimetres.
    assert np.max(np.abs(height[level == selection.flat_level - 1])) > 10.0 * tol


@pytest.mark.parametrize("wind", [0.0, 1.0, 5.0, 9.4, 22.6, 40.0])
def test_detail_maps_keep_each_waves_direction_and_length(wind, monkeypatch):
    # Each detail map holds waves on its tile's lattice (k = 2 pi (m, n) / L, so the tile repeats).
    # Snapped at 1-2 cycles a tile, waves went to 0, 45 or 90 degrees and the map showed a square
    # lattice (Beaufort 9's dotted sea). Every wave spans >= DETAIL_MIN_CYCLES = 5 cycles of its tile,
    # so rounding (m, n) moves its wave vector by <= sqrt(0.5) cycles: <= asin(0.707 / 5) = 8.1 deg in
    # direction and 14 % in length; waves too short for every map go to the roughness, none is lost.
    import math

    from igserver.render.water.detail import (DETAIL_MAPS, DETAIL_MIN_WAVES, _detail_bands, detail_tiles,
                                               detail_unresolved_var)

    import igserver.render.water.detail as detail

    scene = sea_scene(weather={"wind_speed": wind})
    sea = sea_surface(scene.ocean, scene.weather)
    d = sea.detail
    monkeypatch.setattr(detail, "DETAIL_LATTICE_FILL", False)  # the snapped waves (the fill: next test)
    tiles = detail_tiles(sea, 0.0)
    _, band = _detail_bands(sea)
    kept = 0
    for c, (size, waves) in enumerate(tiles):
        k_true = d.k[band == c, None] * d.direction[band == c]
        assert len(waves) == len(k_true)
        kept += len(waves)
        if not len(waves):
            continue
        # a finer tile of a few waves would show its period: those go to the roughness
        assert c == 0 or len(waves) >= DETAIL_MIN_WAVES
        k_snap = waves[:, :2] * 2.0 * math.pi / size
        assert np.linalg.norm(waves[:, :2], axis=1).min() >= 5.0 - 0.5
        cos = np.sum(k_snap * k_true, axis=1) / (np.linalg.norm(k_snap, axis=1) * np.linalg.norm(k_true, axis=1))
        assert np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))).max() <= 8.2
        assert np.abs(np.linalg.norm(k_snap, axis=1) / np.linalg.norm(k_true, axis=1) - 1.0).max() <= 0.15
        assert waves[:, 2] == pytest.approx(d.amplitude[band == c] * np.linalg.norm(k_snap, axis=1))
    lost = band >= DETAIL_MAPS
    assert kept + np.count_nonzero(lost) == d.n
    assert detail_unresolved_var(sea) == pytest.approx(float(np.sum((d.amplitude[lost] * d.k[lost]) ** 2) / 2.0))


@pytest.mark.parametrize("wind", [0.0, 5.0, 22.6])
def test_filled_detail_maps_keep_their_band_slope_and_the_winds_direction(wind, monkeypatch):
    """A filled map (detail.py DETAIL_LATTICE_FILL) holds its band's lattice points, 5 to 38.5 cycles a
    tile, with the slope variance of the detail waves it replaces, travelling with the wind: the slope
    variance's mean direction within 5 deg of the wind sea's, none of it against the wind (beyond 90 deg
    off it under 1 %), at least 500 points a map; each point's frequency is the deep-water one of its
    wave number, and a map's fill is the same from frame to frame but for the phases."""
    import math

    import igserver.render.water.detail as detail

    scene = sea_scene(weather={"wind_speed": wind})
    sea = sea_surface(scene.ocean, scene.weather)
    monkeypatch.setattr(detail, "DETAIL_LATTICE_FILL", False)
    snapped = detail.detail_tiles(sea, 0.0)
    monkeypatch.setattr(detail, "DETAIL_LATTICE_FILL", True)
    filled, later = detail.detail_tiles(sea, 0.0), detail.detail_tiles(sea, 1.0)
    az = math.radians(sea.spectrum.azimuth_to)
    wind_dir = np.array([math.sin(az), math.cos(az)])
    for (size, want), (size_f, got), (_, got_later) in zip(snapped, filled, later):
        assert size_f == size
        if not len(want):
            assert not len(got)
            continue
        r = np.linalg.norm(got[:, :2], axis=1)
        assert len(got) >= 500 and r.min() >= 5.0 and r.max() < 38.5
        variance = got[:, 2] ** 2 / 2.0
        assert variance.sum() == pytest.approx(float(np.sum(want[:, 2] ** 2) / 2.0), rel=1e-9)
        unit = got[:, :2] / r[:, None]
        mean = (variance[:, None] * unit).sum(axis=0)
        assert np.degrees(np.arccos(mean @ wind_dir / np.linalg.norm(mean))) < 5.0
        assert variance[unit @ wind_dir < 0.0].sum() < 0.01 * variance.sum()
        assert np.array_equal(got[:, :3], got_later[:, :3]) and not np.array_equal(got[:, 3], got_later[:, 3])
        omega = np.sqrt(9.80665 * r * 2.0 * math.pi / size)
        step = np.angle(np.exp(1j * (got[:, 3] - got_later[:, 3])))
        assert np.allclose(step, np.angle(np.exp(1j * omega)), atol=1e-6)


@pytest.mark.parametrize("wind", [12.0, 22.6])
def test_drawn_foam_is_calibrated_to_monahans_coverage(wind):
    # The shader's foam (J edge now and FOAM_LAG seconds ago, the wind rows, then the streak dither,
    # mean foam_mean, old foam at half its brightness) averages Monahan's whitecap fraction
    # W = 3.84e-6 U^3.41 (1.8 % at 12 m/s, 16 % at 22.6) over the sea's area. Checked on fresh points
    # and instants, not the calibration's: within 25 % (the field is correlated over a wavelength: a
    # few hundred independent samples below the threshold at 12 m/s).
    from igserver.render.water.foam import (FOAM_LAG, FOAM_SOFT, drawn_foam_threshold, foam_coverage, foam_mean,
                                            streak_opacity)
    from igserver.water.surface import whitecap_coverage

    scene = sea_scene(weather={"wind_speed": wind})
    sea = sea_surface(scene.ocean, scene.weather)
    threshold = drawn_foam_threshold(sea, wind)
    xy = np.random.default_rng(5).uniform(-2000, 2000, (5000, 2))

    def jacobian(lag):
        return np.concatenate([sea.evaluate(xy, t - lag, full=False)["jacobian"] for t in (3.0, 50.0, 111.0, 170.0)])

    j = jacobian(0.0)
    drawn = np.average(foam_coverage(threshold, j, tuple(jacobian(lag) for lag in FOAM_LAG), streak_opacity(wind)),
                       weights=j)
    assert drawn == pytest.approx(whitecap_coverage(wind), rel=0.25)
    # the dither's mean in closed form against the dither itself over a uniform u
    u = (np.arange(4000) + 0.5) / 4000
    for f in (0.0, 0.1, 0.3, 0.5, 0.8, 0.95, 1.0):
        dither = np.clip((f - (1.0 - FOAM_SOFT) * u) / FOAM_SOFT, 0.0, 1.0).mean()
        assert foam_mean(np.array(f)) == pytest.approx(dither, abs=1e-4)
    assert drawn_foam_threshold(sea_surface(scene.ocean, Weather(wind_speed=0.0)), 0.0) == -1.0


@pytest.mark.parametrize("wind, height, pitch", [(22.6, 200.0, -45.0), (22.6, 1000.0, -60.0), (12.0, 200.0, -45.0)])
def test_whitecaps_on_screen_follow_monahans_coverage(renderer, wind, height, pitch):
    # Monahan's whitecap fraction W (16 % at 22.6 m/s, 1.8 % at 12). The foam used to be the J
    # quantile softened by its edge and halved by a streak texture (3 % of the screen at Beaufort 9
    # from 15 m), and from the air the LOD fades the short waves out of the mesh and flattens J (foam
    # all but gone): the drawn fraction is now calibrated, and the faded waves' J variance keeps the
    # foam's probability. Measured per pixel between the frame without whitecaps (threshold -1) and
    # the frame all white (threshold 10), in the HDR target's luminance, averaged over the sea below the
    # horizon. Within a factor 2 of W: the screen weighs the surface by its projected area (crests
    # are compressed and tilted), a frame holds a few dozen dominant wavelengths, and from 1 km the
    # faded waves' part is a normal approximation (measured: 1.7x, 1.5x, 1.4x of W).
    from igserver.water.surface import whitecap_coverage

    scene = sea_scene(camera={"position": [0.0, 0.0, height], "pitch": pitch, "width": 240, "height": 135,
                              "exposure_ev": 13.0}, weather={"wind_speed": wind})
    water = renderer.graph.passes["water"]
    frames = {}
    try:
        for name, threshold in (("drawn", None), ("bare", -1.0), ("white", 10.0)):
            water.foam_threshold = threshold
            renderer.render(scene)  # the HDR target: the tone map's curve would weigh thin foam up
            frames[name] = (renderer.read_hdr()[..., :3].astype(np.float64) @ np.asarray(LUMA))[int(0.55 * 135):]
    finally:
        water.foam_threshold = None
    span = frames["white"] - frames["bare"]
    assert np.all(span > 0.02 * np.median(span))  # foam is brighter than the bare sea everywhere in these views
    coverage = float(np.mean(np.clip((frames["drawn"] - frames["bare"]) / span, 0.0, 1.0)))
    want = whitecap_coverage(wind)
    assert want / 2.0 < coverage < 2.0 * want, (coverage, want)


def test_foam_streak_noise_is_about_normal(renderer):
    # The foam's dither (foam_streaks.glsl) keeps the calibrated mean only if its noise z, a sum of
    # lookups of the tabulated two-octave noise (stored as 0.5 + z / 8 per channel), is standard
    # normal: each channel's deciles within 0.08 of the normal's and its standard deviation within 5 %
    # of 1 (measured 0.04 and 1.001 for the first: 512² texels of 64² noise cells are a few thousand
    # independent samples; the coarser second and third channels, 32 x 16 and 32 x 4 cells, 0.991 and
    # 0.993). The channels are independent noises (correlation under 0.1), the fourth unused.
    from scipy.stats import norm

    scene = sea_scene(weather={"wind_speed": 22.6})
    renderer.render(scene)
    tex = renderer.graph.passes["water"]._foam_noise()
    z = 8.0 * np.frombuffer(tex.read(), dtype=np.uint8).reshape(-1, 4).astype(np.float64) / 255.0 - 4.0
    levels = np.linspace(0.1, 0.9, 9)
    for channel in range(3):
        deciles = np.quantile(z[:, channel], levels)
        assert np.abs(deciles - norm.ppf(levels)).max() < 0.08, (channel, deciles)
        assert abs(z[:, channel].std() - 1.0) < 0.05, (channel, z[:, channel].std())
    correlation = np.corrcoef(z[:, :3].T)
    assert np.abs(correlation - np.eye(3)).max() < 0.1, correlation


def test_minified_detail_maps_leave_the_picture(renderer):
    # Far blocks read the tile average of the detail maps that are minified there (the sampler would
    # read the 2x2 level or coarser: each wave averaged to <= 13 % of its slope) instead of sampling
    # them: the picture must not move by more than a level.
    from igserver.render.water.detail import detail_means, detail_tiles

    scene = sea_scene(camera={"position": [0.0, 0.0, 30.0], "pitch": -15.0, "width": 160, "height": 90})
    water = renderer.graph.passes["water"]
    fast, full, stats = with_and_without_skip(renderer, scene, "skip_minified_maps")
    by_maps = stats["blocks_by_detail_maps"]
    assert sum(by_maps[:-1]) > len(by_maps) and by_maps[-1] < sum(by_maps)  # maps were skipped
    # The average in float64 against the box-filtered float32 map: a level at most.
    assert np.abs(fast.astype(int) - full.astype(int)).max() <= 1
    # The tile averages are what the maps' top mip level holds.
    sea = sea_surface(scene.ocean, scene.weather)
    tiles = detail_tiles(sea, scene.time.sim_time)
    means = detail_means(tiles)
    for c, (_, waves) in enumerate(tiles):
        if len(waves):
            tex = water._detail[c]
            top = int(np.log2(tex.size[0]))
            texel = np.frombuffer(tex.read(level=top), dtype=np.float32).astype(np.float64)
            # float32 sums over 128² texels: the slope means are 0 in exact arithmetic.
            assert texel[2:] == pytest.approx(means[c, 2:], rel=1e-4)
            assert np.abs(texel[:2]).max() < 1e-5 * np.sqrt(means[c, 2:].max())


def test_hull_boxes_follow_the_entities_and_the_camera():
    # hull_boxes is memoised on the visible entities' models and poses, the camera position and the
    # sea level: each of those must still move the boxes (against a cold computation every time).
    from igserver.render.camera import make_view
    from igserver.render.water.hulls import _hull_boxes, hull_boxes
    from igserver.scene import load_scene

    scene = load_scene("demo")
    boat = next(i for i, e in enumerate(scene.entities) if model_has_hull(e.model))
    states = [scene,
              apply_patch(scene, {"camera": {"position": [1.0, -120.0, 6.0]}}),
              _patch_entity(scene, boat, {"position": [float(scene.entities[boat].position[0]) + 3.0,
                                                      *scene.entities[boat].position[1:]]}),
              _patch_entity(scene, boat, {"heading": float(scene.entities[boat].heading) + 20.0}),
              _patch_entity(scene, boat, {"visible": False}),
              scene]
    results = []
    for s in states:
        view = make_view(s.camera)
        got = hull_boxes(s, view)
        cold = _hull_boxes(s, view)
        assert len(got) == len(cold) and all(np.array_equal(a, b) for a, b in zip(got, cold))
        results.append(got)
    for moved in results[1:5]:  # every change moved at least one box (or dropped the boat's)
        assert len(moved) != len(results[0]) or any(not np.array_equal(a, b) for a, b in zip(moved, results[0]))
    assert all(np.array_equal(a, b) for a, b in zip(results[0], results[5]))


def model_has_hull(model: str) -> bool:
    from igserver.render.water.hulls import model_hulls
    return model == "patrol_boat" and bool(model_hulls(model))


def _patch_entity(scene: Scene, index: int, change: dict) -> Scene:
    entities = [e.model_dump() for e in scene.entities]
    entities[index].update(change)
    return Scene.model_validate({**scene.model_dump(), "entities": entities})


def test_blocks_near_hulls_matches_the_corner_test_for_turned_boxes():
    # The footprint of a turned, tilted box from its matrix (centre ± Σ|column|) against the
    # footprint of its 8 corners, for random boxes and blocks: the same blocks.
    from igserver.render.camera import body_to_world
    from igserver.render.water.hulls import blocks_near_hulls

    rng = np.random.default_rng(3)
    hulls = []
    for _ in range(12):
        m = np.eye(4)
        m[:3, :3] = body_to_world(*rng.uniform(-180, 180, 3) * (1.0, 0.2, 0.2)) @ np.diag(rng.uniform(0.3, 20.0, 3))
        m[:3, 3] = rng.uniform(-200.0, 200.0, 3)
        hulls.append(np.linalg.inv(m))
    nodes = np.column_stack([rng.uniform(-300, 300, (4000, 2)), rng.choice([2.0, 8.0, 64.0], 4000),
                             np.zeros(4000)]).astype(np.float32)
    corners = np.array([[x, y, z, 1.0] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
    expected = np.zeros(len(nodes), dtype=bool)
    x0, y0, side = (nodes[:, c].astype(np.float64) for c in range(3))
    for inv in hulls:
        pts = corners @ np.linalg.inv(inv).T
        lo, hi = pts[:, :2].min(axis=0) - 2.0, pts[:, :2].max(axis=0) + 2.0
        expected |= (x0 <= hi[0]) & (x0 + side >= lo[0]) & (y0 <= hi[1]) & (y0 + side >= lo[1])
    got = blocks_near_hulls(nodes, hulls, margin=2.0)
    assert 0 < np.count_nonzero(expected) < len(nodes)  # the draw exercises both answers
    assert np.array_equal(got, expected)


def test_block_selection_is_reused_only_for_the_same_view_and_sea(renderer):
    # The LOD selection is memoised on the view, the sea and the knobs: a later time reuses it; a
    # turned or moved camera, another wind or another LOD bound gets a fresh one equal to lod.select.
    from igserver.render.camera import make_view

    water = renderer.graph.passes["water"]
    base = sea_scene()
    first = water.select(sea_surface(base.ocean, base.weather), base, make_view(base.camera))
    later = apply_patch(base, {"time": {"sim_time": 250.0}})
    assert water.select(sea_surface(later.ocean, later.weather), later, make_view(later.camera)) is first
    for change in ({"camera": {"heading": 31.0}}, {"camera": {"position": [0.0, 5.0, 12.0]}},
                   {"weather": {"wind_speed": 14.0}}, {"ocean": {"lod_error": 0.25}}, {"ocean": {"level": 0.5}}):
        s = apply_patch(base, change)
        sea, view = sea_surface(s.ocean, s.weather), make_view(s.camera)
        got = water.select(sea, s, view)
        assert got is not first
        cold = lod.select(view, float(view.position[2] - s.ocean.level), sea.waves.k, sea.waves.amplitude,
                          s.camera.fov_y, min(s.ocean.lod_error, 16.0), view.far)
        assert np.array_equal(got.nodes, cold.nodes) and np.array_equal(got.morph, cold.morph)
    # The finest-spacing rule (the quality study's knob) is part of the key too.
    sea, view = sea_surface(base.ocean, base.weather), make_view(base.camera)
    saved = lod.SPACING_PER_WAVE
    try:
        lod.SPACING_PER_WAVE = saved / 2.0
        coarser = water.select(sea, base, view)
    finally:
        lod.SPACING_PER_WAVE = saved
    assert coarser.finest_spacing == 2.0 * first.finest_spacing
    assert water.select(sea, base, view).finest_spacing == first.finest_spacing


def test_faded_foam_streaks_leave_the_picture(renderer):
    # Blocks where every pixel spans 3/4 of a streak cell (water.py foam_streaks_needed: the shader's
    # contrast is exactly 0 there) are drawn without the streak noise: a Beaufort 9 sea, whitecaps on
    # every crest, from 300 m (the near blocks keep the noise, the far ones not) must be the same
    # frame as with the noise read on every block.
    scene = sea_scene(camera={"position": [0.0, 0.0, 300.0], "pitch": -10.0, "width": 320, "height": 180},
                      weather={"wind_speed": 22.6})
    fast, full, stats = with_and_without_skip(renderer, scene, "skip_faded_streaks")
    assert 0 < stats["foam_streak_blocks"] < stats["blocks"]
    np.testing.assert_array_equal(fast, full)
