"""The detail maps' synthesis on the GL (render/water/detail_synth.py) against the direct per-level
construction (one spectrum per level from the waves, detail_mips.py ``band_limited_levels``), and its
caches: each keyed by its whole input, built again when an input changes and only then."""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import synthesized_levels

from igserver.render.water import detail, detail_synth
from igserver.render.water.detail import detail_means, detail_tiles
from igserver.render.water.detail_mips import band_limited_levels
from igserver.scene import Scene, apply_patch
from igserver.water import sea_surface

# The GL's levels against the float64 reference, as a fraction of level 0's largest value: the phases
# are reduced in double precision, their sines and the DFTs (7 radix-2 stages at 128²) run in float32,
# each rounding ~6e-8 of a partial sum. Measured at most 2.0e-7 (every tile and level below).
TOLERANCE = 4e-7


def _sea(wind: float = 22.6):
    scene = apply_patch(Scene(), {"ocean": {"enabled": True}, "weather": {"wind_speed": wind}})
    return sea_surface(scene.ocean, scene.weather)


def _shared_points_tile() -> np.ndarray:
    """A tile with two waves on one lattice point, one on the opposite point, and (at 32 texels) a
    wave past Nyquist: the sums and pairings the synthesis must keep."""
    rng = np.random.default_rng(3)
    mn = np.array([[5, 3], [5, 3], [-5, -3], [12, 0], [-20, 0], [7, -9], [0, 6], [-11, 4], [14, 13]], float)
    slope = rng.uniform(0.02, 0.1, len(mn))
    phase = rng.uniform(0.0, 2.0 * math.pi, len(mn))
    return np.column_stack([mn, slope, phase])


def _tiles():
    tiles = [w for _, w in detail_tiles(_sea(), 12.3) if len(w)]
    return tiles + [_shared_points_tile()]


def _assert_levels(got: list[np.ndarray], want: list[np.ndarray]) -> None:
    assert [lv.shape for lv in got] == [lv.shape for lv in want]
    scale = float(np.abs(want[0]).max())
    for level, (a, b) in enumerate(zip(got, want)):
        error = np.abs(a.astype(np.float64) - b).max()
        assert error <= TOLERANCE * scale, (level, error / scale)


@pytest.mark.parametrize("resolution", [32, 128, 256])
def test_levels_equal_the_direct_construction(renderer, resolution):
    tiles = _tiles()
    for waves, levels in zip(tiles, synthesized_levels(renderer, tiles, resolution)):
        _assert_levels(levels, band_limited_levels(waves, resolution))
        means = detail_means([(1.0, waves)])[0]
        assert np.allclose(levels[-1][0, 0], means, rtol=1e-6, atol=1e-12)


def test_the_phases_follow_the_time_in_double_precision(renderer):
    # φ = φ0 − ω t reduced on the GL as detail_tiles does on the host: at t = 1e6 s (ω t ~ 1e7 rad)
    # and at a later frame the levels are those of the host's phases.
    sea = _sea()
    lattice = detail._lattice_of(sea)
    static = [(w, o, p) for (_, w, o, p) in lattice.tiles if len(w)]
    tiles = [np.column_stack([w, p]) for w, _, p in static]
    for t in (1e6 + 0.25, 1e6 + 0.25 + 1 / 30):
        got = synthesized_levels(renderer, tiles, 64, t, omegas=[o for _, o, _ in static])
        host = [w for _, w in detail_tiles(sea, t) if len(w)]
        for levels, waves in zip(got, host):
            _assert_levels(levels, band_limited_levels(waves, 64))


def test_the_tables_are_built_once_per_lattice_and_resolution():
    detail_synth.synth_tables.cache_clear()
    info = detail_synth.synth_tables.cache_info
    sea = _sea()
    first = detail.detail_synth_tables(sea, 64)
    assert detail.detail_synth_tables(sea, 64) is first  # another frame: the same tables
    assert info().misses == 1
    assert detail.detail_synth_tables(sea, 128) is not first  # another resolution
    assert info().misses == 2
    detail.detail_synth_tables(_sea(12.0), 64)  # another sea state: other waves
    assert info().misses == 3


def test_the_pairs_are_found_once_per_lattice():
    # detail_means and the tables share a lattice's pairs; only the lattice's (m, n, A k) build them
    # anew, not the phases.
    detail_synth.tile_pairs.cache_clear()
    waves = _tiles()[-1]
    for phase_shift in (0.0, 0.7):
        shifted = waves.copy()
        shifted[:, 3] += phase_shift
        detail_means([(1.0, shifted)])
    assert detail_synth.tile_pairs.cache_info().misses == 1
    stronger = waves.copy()
    stronger[:, 2] *= 2.0
    assert np.allclose(detail_means([(1.0, stronger)])[0], 4.0 * detail_means([(1.0, waves)])[0])
    assert detail_synth.tile_pairs.cache_info().misses == 2


def test_the_lattice_is_built_once_per_sea():
    detail.detail_lattice.cache_clear()
    info = detail.detail_lattice.cache_info
    sea = _sea()
    first = detail_tiles(sea, 12.3)
    for t in (13.0, 1e6 + 0.25):
        tiles = detail_tiles(sea, t)
        assert [s for s, _ in tiles] == [s for s, _ in first]
        assert all(np.array_equal(a[:, :3], b[:, :3]) for (_, a), (_, b) in zip(tiles, first))
    detail.detail_unresolved_var(sea)
    assert info().misses == 1
    other = _sea(12.0)  # another sea state: other waves
    other_tiles = detail_tiles(other, 12.3)
    assert info().misses == 2
    assert [s for s, _ in other_tiles] != [s for s, _ in first]


def test_tiles_phases_follow_the_dispersion():
    # φ(t) = φ0 − ω t with ω = sqrt(g k) of the snapped wave (mod 2π), exact at large t too.
    sea = _sea()
    t0, dt = 1e6, 0.37
    for (size, a), (_, b) in zip(detail_tiles(sea, t0), detail_tiles(sea, t0 + dt)):
        if not len(a):
            continue
        omega = np.sqrt(9.80665 * np.linalg.norm(a[:, :2], axis=1) * 2.0 * math.pi / size)
        step = np.angle(np.exp(1j * (a[:, 3] - b[:, 3])))
        assert np.allclose(step, np.angle(np.exp(1j * omega * dt)), atol=1e-6)


def test_the_pass_writes_the_frames_levels(renderer):
    # After frames at other times, each map's texture levels are the levels of the last frame's time;
    # a frame at the same time writes nothing, and no frame makes a GL object.
    scene = apply_patch(Scene(), {"ocean": {"enabled": True}, "weather": {"wind_speed": 12.0},
                                  "camera": {"position": [0.0, 0.0, 3.0], "pitch": -10.0, "width": 64, "height": 36}})
    water = renderer.graph.passes["water"]
    copied = []
    for t in (50.0, 50.5, 51.25):
        renderer.render(apply_patch(scene, {"time": {"sim_time": t}}))
        copied.append(water._detail_synth.levels_copied)
    synth = water._detail_synth
    # after the first frame, only the levels that change with t are copied again (the coarse ones
    # that hold no wave are the same at every t and stay in the textures)
    varying = sum(sum(v) for v in synth._tables.varies[:water._maps_written])
    assert 0 < varying < sum(len(v) for v in synth._tables.varies[:water._maps_written])
    assert copied[2] - copied[1] == varying
    buffers = dict(synth._buffers)
    written = synth.maps_written
    renderer.render(apply_patch(scene, {"time": {"sim_time": 51.25}}))  # the same instant: the maps held
    assert synth.maps_written == written and synth._buffers == buffers
    sea = sea_surface(scene.ocean, scene.weather)
    checked = 0
    for c, (_, waves) in enumerate(detail_tiles(sea, 51.25)[:water._maps_written]):
        if not len(waves):
            continue
        tex = water._detail[c]
        want = band_limited_levels(waves, tex.size[0])
        got = [np.frombuffer(tex.read(level=level), np.float32).reshape(lv.shape) for level, lv in enumerate(want)]
        _assert_levels(got, want)
        checked += 1
    assert checked >= 1


def test_the_means_a_frame_reads_are_those_of_the_frames_phases():
    # detail_means_at holds a map's average while no pair of its waves follows t (pairs on one lattice
    # point share ω): at every t, the tile averages of the phases at t (detail_tiles, detail_means).
    sea = _sea()
    first = detail.detail_means_at(sea, 3.0)
    for t in (3.0, 17.25, 1e6 + 0.5):
        want = detail_means([(size, waves) for size, waves in detail_tiles(sea, t)])
        assert np.allclose(detail.detail_means_at(sea, t), want, rtol=1e-9, atol=1e-15)
    assert np.array_equal(detail.detail_means_at(sea, 1e6 + 0.5), first)
    assert detail.detail_fixed_tiles(sea) is detail.detail_fixed_tiles(sea)  # per sea state, not per frame


def test_a_map_with_waves_on_opposite_points_follows_t():
    # waves on (5, 3) and (-5, -3): their product averages to ½ cos(φ_i + φ_j), which turns with t
    lattice = detail.DetailLattice.__new__(detail.DetailLattice)
    fixed = np.array([[5.0, 3.0, 0.05], [-5.0, -3.0, 0.04], [7.0, -9.0, 0.03]])
    omega = np.sqrt(9.80665 * np.linalg.norm(fixed[:, :2], axis=1) * 2 * math.pi / 10.0)
    phase = np.array([0.3, 1.1, 2.0])
    lattice.tiles = [(10.0, fixed, omega, phase)]
    lattice.fixed_tiles = [(10.0, fixed)]
    lattice._pairs = [detail_synth.TilePairs(fixed)]
    assert detail.still_means(lattice.tiles, lattice._pairs) == []
    assert detail.still_means(lattice.tiles, [detail_synth.TilePairs(fixed[[0, 0, 2]])]) == [0]  # one point
    lattice._still_means = {}
    for t in (0.0, 0.7, 2.2):
        waves = np.column_stack([fixed, np.mod(phase - np.mod(omega * t, 2 * math.pi), 2 * math.pi)])
        assert np.allclose(lattice.means(t)[0], detail_means([(10.0, waves)])[0], rtol=1e-12)
    assert not np.allclose(lattice.means(0.0), lattice.means(0.7))


def test_pairs_are_those_of_every_two_waves():
    # The table of lattice points finds the same pairs as comparing every two waves (same point:
    # w follows φ_i − φ_j, opposite points: φ_i + φ_j), in the same order.
    from igserver.render.water.detail_synth import _pairs

    rng = np.random.default_rng(5)
    tiles = [_shared_points_tile()[:, :2], rng.integers(-4, 5, (300, 2)).astype(float), _tiles()[0][:, :2]]
    for mn in tiles:
        same = np.all(mn[:, None] == mn[None], axis=2)
        opposite = np.all(mn[:, None] == -mn[None], axis=2)
        i, j = np.nonzero((same | opposite) & ~np.eye(len(mn), dtype=bool))
        got = _pairs(mn)
        assert np.array_equal(got[0], i) and np.array_equal(got[1], j)
        assert np.array_equal(got[2], np.where(opposite[i, j], 1.0, -1.0))
    assert len(_pairs(tiles[1])[0]) > 300  # a tile of many shared points
