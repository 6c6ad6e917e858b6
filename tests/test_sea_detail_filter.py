"""The sea's detail maps filtered by their screen footprint (water/detail_filter.glsl, detail_mips.py):
no diamond lattice in the near ripples seen level from 2 m, less shimmer for a moving camera, band-
limited mip levels. 640x360 frames (the lattice is a few pixels a cell), the session renderer."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import synthesized_levels

import igserver.render.water.water as water_module
from igserver.photometry import LUMA
from igserver.scene import Scene, apply_patch

NEAR = slice(240, 360)  # rows of the near water at 640x360, 3.5-12 m off, seen level from 2 m (fov 60 deg)


def _level_view(renderer, x: float = 0.0, t: float = 100.0, size=(640, 360)) -> np.ndarray:
    """RGB (0..255) of a level view from 2 m over the default sea (wind 5 m/s), at the exposure
    the eye settles to there (a fixed one: frames compare alike whatever was rendered before)."""
    scene = apply_patch(Scene(), {"ocean": {"enabled": True}, "time": {"sim_time": t},
                                  "camera": {"position": [x, 0.0, 2.0], "pitch": 0.0, "heading": 0.0,
                                             "width": size[0], "height": size[1], "exposure_ev": 14.27}})
    return renderer.render(scene).rgba[..., :3].astype(np.float64)


def _band_power(img: np.ndarray, short: float = 6.0, long: float = 16.0):
    """Power spectrum (Hann-windowed) of img's near rows (its lower third) and the mask of its periods
    of ``short``-``long`` px at 640 across (in proportion at other widths)."""
    h, w = img.shape[:2]
    reg = img[2 * h // 3:] - img[2 * h // 3:].mean()
    win = np.outer(np.hanning(reg.shape[0]), np.hanning(reg.shape[1]))
    power = np.abs(np.fft.fft2(reg * win)) ** 2
    f = np.hypot(np.fft.fftfreq(reg.shape[0])[:, None], np.fft.fftfreq(reg.shape[1])[None, :])
    return power, (f > 640.0 / (w * long)) & (f < 640.0 / (w * short))


def _lattice(renderer, monkeypatch, size=(640, 360)) -> float:
    """The finer detail maps' part of the near water (the frame less the frame without maps 1 and 2:
    the lattice itself): its strongest 6-16 px spectral peak (at 640 across) over the whole frame's
    mean power there."""
    full = _level_view(renderer, size=size)
    with monkeypatch.context() as m:
        tiles = water_module.detail_fixed_tiles
        m.setattr(water_module, "detail_fixed_tiles",
                  lambda sea: [(s, w if c == 0 else w[:0]) for c, (s, w) in enumerate(tiles(sea))])
        coarse = _level_view(renderer, size=size)
    part, band = _band_power((full - coarse) @ LUMA)
    background, _ = _band_power(full @ LUMA)
    return float(part[band].max() / background[band].mean())


def _shimmer(renderer, speed: float = 5.0, fps: float = 30.0) -> float:
    """Fraction of near-water pixels (below the horizon) of which a channel changes by more than 32
    levels between two frames of a camera moving sideways at ``speed`` m/s: frames 2 and 3 of a
    stream (the first one starts it: a frame that follows no other shows a still eye)."""
    frames = [_level_view(renderer, x=i * speed / fps, t=100.0 + i / fps) for i in range(3)]
    return float(np.mean(np.abs(frames[2] - frames[1]).max(axis=-1)[200:] > 32.0))


@pytest.fixture
def unfaded(renderer):
    water = renderer.graph.passes["water"]
    yield water
    water.detail_fade = True


def test_near_ripples_show_no_lattice(renderer, monkeypatch, unfaded):
    """A level view from 2 m: the finer detail map (a tile of a dozen waves at snapped directions) drew
    a diamond lattice over the near water, its spectral peak 9.0 x the frame's mean power at 6-16 px.
    Faded by the footprint (its longest wave under 16 px) the peak is under 1/4 of that and under half
    the frame's mean (0.03 measured)."""
    unfaded.detail_fade = False
    before = _lattice(renderer, monkeypatch)
    unfaded.detail_fade = True
    after = _lattice(renderer, monkeypatch)
    assert after < 0.25 * before and after < 0.5, (before, after)


@pytest.mark.parametrize("speed, unfaded_share", [(2.0, 0.005), (5.0, 0.05), (10.0, 0.10), (20.0, 0.15)])
def test_moving_camera_does_not_shimmer(renderer, unfaded, speed, unfaded_share):
    """Sideways at 2-20 m/s, 30 frames/s: the share of near-water pixels changing by more than 32 levels
    from one frame to the next is 0.7, 5.6, 12 and 17 % with the maps unfiltered (the ripples shift by
    most of a period between frames and show an unrelated phase in each), and was still 0.2, 4.0,
    8.5 and 11.8 % filtered by the pixel's footprint alone. Blurred over the eye's motion across the
    frame (detail_filter.glsl) it is under 0.5 % at every speed (0.12, 0.00, 0.00, 0.39 measured):
    what changes then is the mesh's waves, which move smoothly."""
    unfaded.detail_fade = False
    before = _shimmer(renderer, speed)
    unfaded.detail_fade = True
    after = _shimmer(renderer, speed)
    assert before > unfaded_share, before
    assert after < 0.005, (before, after)


def test_filled_tiles_show_no_lattice_where_resolved(monkeypatch):
    """Seen level from 2 m at 1280x720 the finer map is resolved, so the footprint filter leaves it:
    a tile of the detail waves snapped to its lattice (a dozen directions) drew a diamond lattice
    there, its spectral peak at 12-32 px 4.5x the frame's mean power. Filled with every lattice wave of
    its band (detail.py DETAIL_LATTICE_FILL: a continuous spectrum on the tile) the peak is under half
    of that (1.92 measured: what is left is the tile's own period, 1.3 m, the lattice of its
    repetitions), and the map's mean-square slope is the snapped waves' (within 1 %)."""
    import igserver.render.water.detail as detail
    from igserver.render.renderer import Renderer
    from igserver.water import sea_surface

    scene = apply_patch(Scene(), {"ocean": {"enabled": True}})
    sea = sea_surface(scene.ocean, scene.weather)
    renderer = Renderer()
    try:
        peaks, variances = {}, {}
        for fill in (False, True):
            monkeypatch.setattr(detail, "DETAIL_LATTICE_FILL", fill)
            renderer.graph.passes["water"]._detail_key = None  # the maps anew for the same time
            variances[fill] = [float(np.sum(w[:, 2] ** 2) / 2.0) for _, w in detail.detail_tiles(sea, 100.0)]
            peaks[fill] = _lattice(renderer, monkeypatch, size=(1280, 720))
    finally:
        renderer.release()
    assert peaks[True] < 0.5 * peaks[False], peaks
    assert np.allclose(variances[True], variances[False], rtol=0.01), variances


def test_still_eye_and_single_frames_are_not_blurred(renderer):
    """The motion blur needs a stream: a frame that follows the previous one by 1/30 s with the eye
    20 cm aside is blurred (less near-ripple detail than the same state drawn again on its own); a
    re-render at the same time, a step back in time and a still eye see no motion."""
    first = _level_view(renderer, x=0.0, t=50.0)
    streamed = _level_view(renderer, x=0.2, t=50.0 + 1 / 30)
    alone = _level_view(renderer, x=0.2, t=50.0 + 1 / 30)  # the same instant again: no motion
    detail = lambda img: float(np.abs(np.diff(img[NEAR] @ LUMA, axis=1)).mean())
    assert detail(streamed) < 0.8 * detail(alone), (detail(streamed), detail(alone))
    assert np.array_equal(_level_view(renderer, x=0.0, t=50.0), first)  # back in time: a new stream
    _level_view(renderer, x=0.0, t=60.0)
    still = _level_view(renderer, x=0.0, t=60.0 + 1 / 30)
    assert np.array_equal(still, _level_view(renderer, x=0.0, t=60.0 + 1 / 30))


@pytest.mark.parametrize("resolution", [32, 128])
def test_mip_levels_carry_only_the_waves_they_can(renderer, resolution):
    """Band-limited mip levels (detail_mips.py): level L (N_L texels a side) is the direct sum, at its
    own texel centres, of the tile's waves with gain 1 - smoothstep(1/2, 1, max(|m|, |n|) / (N_L / 2))
    (none at its Nyquist: nothing folds onto a longer wave); its second moments add the variance the
    gains removed, so each level's tile mean of (sx^2, sy^2) is level 0's, and the 1x1 level is the
    tile average detail_means computes (LEAN mapping's moments, Olano & Baker 2010)."""
    from igserver.render.water.detail import detail_means, detail_tiles
    from igserver.water import sea_surface

    scene = apply_patch(Scene(), {"ocean": {"enabled": True}, "weather": {"wind_speed": 22.6}})
    sea = sea_surface(scene.ocean, scene.weather)
    tiles = [(size, waves) for size, waves in detail_tiles(sea, 12.3) if len(waves)]
    assert len(tiles) >= 2
    maps = synthesized_levels(renderer, [waves for _, waves in tiles], resolution)
    for (size, waves), levels in zip(tiles, maps):
        mn = waves[:, :2]
        g = waves[:, 2:3] * mn / np.linalg.norm(mn, axis=1, keepdims=True)
        scale = float(np.abs(g).sum())
        total = levels[0][..., 2:].astype(np.float64).mean(axis=(0, 1))
        for level in levels:
            n_l = level.shape[0]
            u = (np.arange(n_l) + 0.5) / n_l
            x, y = np.meshgrid(u, u)
            f = np.max(np.abs(mn), axis=1) / (0.5 * n_l)
            z = np.clip((f - 0.5) / 0.5, 0.0, 1.0)
            gain = 1.0 - z * z * (3.0 - 2.0 * z)
            theta = 2.0 * np.pi * (mn[:, 0, None, None] * x + mn[:, 1, None, None] * y) + waves[:, 3, None, None]
            sx = np.sum((gain * g[:, 0])[:, None, None] * np.cos(theta), axis=0)
            sy = np.sum((gain * g[:, 1])[:, None, None] * np.cos(theta), axis=0)
            assert np.abs(level[..., 0] - sx).max() < 1e-5 * scale
            assert np.abs(level[..., 1] - sy).max() < 1e-5 * scale
            assert np.allclose(level[..., 2:].astype(np.float64).mean(axis=(0, 1)), total, rtol=1e-4, atol=1e-9)
        means = detail_means([(size, waves)])[0]
        assert np.allclose(levels[-1][0, 0], means, rtol=1e-4, atol=1e-9)
