"""The detail maps' per-frame synthesis (render/water/detail_synth.py) against the direct per-level
construction (one spectrum per level from the waves, detail_mips.py ``band_limited_levels``), and its
caches: each keyed by its whole input, built again when an input changes and only then."""

from __future__ import annotations

import math

import numpy as np
import pytest

from igserver.render.water import detail, detail_synth
from igserver.render.water.detail import detail_map_levels, detail_means, detail_tiles
from igserver.render.water.detail_mips import band_limited_levels
from igserver.scene import Scene, apply_patch
from igserver.water import sea_surface


def _sea(wind: float = 22.6):
    scene = apply_patch(Scene(), {"ocean": {"enabled": True}, "weather": {"wind_speed": wind}})
    return sea_surface(scene.ocean, scene.weather)


def _direct_level0(waves: np.ndarray, n_side: int) -> np.ndarray:
    """Level 0 as the inverse DFT of the waves' coefficients added bin by bin (aliased bins summed)."""
    mn = waves[:, 0:2]
    g = waves[:, 2:3] * mn / np.linalg.norm(mn, axis=1, keepdims=True)
    half = 0.5 * (g[:, 0] + 1j * g[:, 1])
    psi = waves[:, 3] + math.pi * (mn[:, 0] + mn[:, 1]) / n_side
    m, n = mn[:, 0].astype(int), mn[:, 1].astype(int)
    spectrum = np.zeros((n_side, n_side), dtype=complex)
    np.add.at(spectrum, (n % n_side, m % n_side), half * np.exp(1j * psi))
    np.add.at(spectrum, (-n % n_side, -m % n_side), half * np.exp(-1j * psi))
    s = np.fft.ifft2(spectrum, norm="forward")
    return np.stack([s.real, s.imag, s.real ** 2, s.imag ** 2], axis=-1).astype(np.float32)


def _shared_points_tile() -> np.ndarray:
    """A tile with two waves on one lattice point, one on the opposite point, and (at 32 texels) a
    wave past Nyquist folding onto another's bin: the sums and pairings the synthesis must keep."""
    rng = np.random.default_rng(3)
    mn = np.array([[5, 3], [5, 3], [-5, -3], [12, 0], [-20, 0], [7, -9], [0, 6], [-11, 4], [14, 13]], float)
    slope = rng.uniform(0.02, 0.1, len(mn))
    phase = rng.uniform(0.0, 2.0 * math.pi, len(mn))
    return np.column_stack([mn, slope, phase])


def _tiles():
    tiles = [w for _, w in detail_tiles(_sea(), 12.3) if len(w)]
    return tiles + [_shared_points_tile()]


@pytest.mark.parametrize("resolution", [32, 128])
def test_levels_equal_the_direct_construction(resolution):
    # Within float32's rounding of the same float64 values (the sums only run in another order).
    for waves in _tiles():
        levels = detail_map_levels(waves, resolution)
        reference = band_limited_levels(waves, resolution)
        assert [lv.shape for lv in levels] == [lv.shape for lv in reference]
        scale = float(np.abs(reference[0]).max())
        for got, want in zip(levels, reference):
            assert got.dtype == np.float32
            assert np.abs(got.astype(np.float64) - want).max() <= 2e-7 * scale
        means = detail_means([(1.0, waves)])[0]
        assert np.allclose(levels[-1][0, 0], means, rtol=1e-6, atol=1e-12)


def test_levels_written_into_held_arrays_are_the_fresh_ones():
    waves = _tiles()[0]
    held = [np.full_like(lv, np.nan) for lv in detail_map_levels(waves, 64)]
    for phase_shift in (0.0, 1.3):
        shifted = waves.copy()
        shifted[:, 3] = np.mod(shifted[:, 3] + phase_shift, 2.0 * math.pi)
        got = detail_map_levels(shifted, 64, out=held)
        assert all(a is b for a, b in zip(got, held))
        for a, b in zip(got, detail_map_levels(shifted, 64)):
            assert np.array_equal(a, b)


def test_the_synthesis_is_built_once_per_lattice_and_resolution():
    detail_synth.detail_synth.cache_clear()
    waves = _tiles()[0]
    info = detail_synth.detail_synth.cache_info
    detail_map_levels(waves, 64)
    assert info().misses == 1
    later = waves.copy()
    later[:, 3] += 0.5  # the time moves only the phases
    detail_map_levels(later, 64)
    assert info().misses == 1
    detail_map_levels(waves, 128)  # another resolution
    assert info().misses == 2
    stronger = waves.copy()
    stronger[0, 2] *= 1.5  # another amplitude
    assert not np.allclose(detail_map_levels(stronger, 64)[0], detail_map_levels(waves, 64)[0])
    assert info().misses == 3
    moved = waves.copy()
    moved[0, 0] += 1.0  # another lattice point
    detail_map_levels(moved, 64)
    assert info().misses == 4


def test_the_pairs_are_found_once_per_lattice():
    # detail_means and every resolution's synthesis share a lattice's pairs; only the lattice's
    # (m, n, A k) build them anew, not the phases.
    detail_synth.tile_pairs.cache_clear()
    detail_synth.detail_synth.cache_clear()
    waves = _tiles()[-1]
    for phase_shift in (0.0, 0.7):
        shifted = waves.copy()
        shifted[:, 3] += phase_shift
        detail_means([(1.0, shifted)])
        detail_map_levels(shifted, 32)
        detail_map_levels(shifted, 64)
    assert detail_synth.tile_pairs.cache_info().misses == 1
    stronger = waves.copy()
    stronger[:, 2] *= 2.0
    assert np.allclose(detail_means([(1.0, stronger)])[0], 4.0 * detail_means([(1.0, waves)])[0])
    assert detail_synth.tile_pairs.cache_info().misses == 2


def test_the_box_chain_has_its_own_synthesis(monkeypatch):
    detail_synth.detail_synth.cache_clear()
    waves = _tiles()[0]
    band = detail_map_levels(waves, 32)
    monkeypatch.setattr(detail, "BAND_LIMITED_MIPS", False)
    box = detail_map_levels(waves, 32)
    assert detail_synth.detail_synth.cache_info().misses == 2
    # the box chain's level 0 holds every wave, aliasing included; the band-limited one drops those
    # past half its Nyquist (the filled tile reaches 38.5 cycles, past 32 texels' 16)
    direct = _direct_level0(waves, 32)
    assert np.abs(box[0].astype(np.float64) - direct).max() <= 2e-7 * float(np.abs(direct).max())
    assert not np.allclose(box[0], band[0]) and not np.allclose(box[1], band[1])


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


def test_the_pass_uploads_the_frames_levels(renderer):
    # The pass fills its held arrays again each frame: after frames at other times, each map's
    # texture levels are exactly the levels computed afresh for the last frame's time.
    scene = apply_patch(Scene(), {"ocean": {"enabled": True}, "weather": {"wind_speed": 12.0},
                                  "camera": {"position": [0.0, 0.0, 3.0], "pitch": -10.0, "width": 64, "height": 36}})
    water = renderer.graph.passes["water"]
    for t in (50.0, 50.5, 51.25):
        renderer.render(apply_patch(scene, {"time": {"sim_time": t}}))
    sea = sea_surface(scene.ocean, scene.weather)
    written = 0
    for c, (_, waves) in enumerate(detail_tiles(sea, 51.25)[:water._maps_written]):
        if not len(waves):
            continue
        tex = water._detail[c]
        for level, want in enumerate(detail_map_levels(waves, tex.size[0])):
            got = np.frombuffer(tex.read(level=level), dtype=np.float32).reshape(want.shape)
            assert np.array_equal(got, want), (c, level)
        written += 1
    assert written >= 1


def test_unchanged_small_levels_are_not_uploaded_again(renderer, monkeypatch):
    # The coarse levels no wave fits hold the tile's moments, constant while no two waves share a
    # lattice point: a later frame uploads the levels that changed only (the readback test above
    # checks that the textures still hold every level of the frame).
    import moderngl

    scene = apply_patch(Scene(), {"ocean": {"enabled": True}, "weather": {"wind_speed": 12.0},
                                  "camera": {"position": [0.0, 0.0, 3.0], "pitch": -10.0, "width": 64, "height": 36}})
    water = renderer.graph.passes["water"]
    renderer.render(apply_patch(scene, {"time": {"sim_time": 70.0}}))
    detail_ids = {id(tex) for tex in water._detail}
    writes = []
    write = moderngl.Texture.write
    monkeypatch.setattr(moderngl.Texture, "write",
                        lambda self, data, *a, level=0, **k: (writes.append(level) if id(self) in detail_ids else None,
                                                              write(self, data, *a, level=level, **k))[1])
    renderer.render(apply_patch(scene, {"time": {"sim_time": 70.5}}))
    resolution = water._detail[0].size[0]
    chain = int(math.log2(resolution)) + 1
    assert water._maps_written >= 1
    assert 0 < len(writes) < water._maps_written * chain
    assert all(level == 0 or resolution >> level > 1 for level in writes)  # the 1x1 moments kept
    assert writes.count(0) == water._maps_written


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
