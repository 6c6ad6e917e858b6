"""The beach on rendered pictures (sea_beach: a 2 % slope, the shore 400 m east; 1 m swell of 11 s
from 240° and an 8 m/s wind sea of 1.5 m and 6 s, which peaks higher: the swash's cadence): swash
running up the sand and back, a shoreline that follows the run-up, wet sand darker than dry, white
breaking crests that move.

Each pixel's world position comes from the distance target and its view ray; on the slope beach its
height above the still water level is 0.02 · (x - 400) (x toward the shore), its water depth the
opposite. Luminance is read in the linear HDR target."""

from __future__ import annotations

import numpy as np
import pytest

from igserver.quality.water_surf import beach_frame, dominant_waves_of, swash_reach
from igserver.render.water.shore import runup_r2
from igserver.scene import apply_patch
from igserver.scene.files import load_scene

SLOPE, SHORE = 0.02, 400.0
SHORE_VIEW = {"camera": {"position": [395.0, -120.0, 4.0], "heading": 30.0, "pitch": -12.0, "width": 240,
                         "height": 135, "exposure_ev": 14.5}}
SURF_VIEW = {"camera": {"width": 240, "height": 135, "exposure_ev": 14.5}}


def beach(patch: dict, t: float):
    scene = load_scene("sea_beach")
    return apply_patch(scene, {**patch, "time": {"sim_time": t}})


H0, TP = dominant_waves_of(load_scene("sea_beach"))  # (H0 m, Tp s) of its waves


def elevation(xy: np.ndarray) -> np.ndarray:
    return SLOPE * (xy[..., 0] - SHORE)


@pytest.fixture(scope="module")
def swash_frames(renderer):
    """Six frames over one swash period from a camera on the beach looking along the shore."""
    out = [beach_frame(renderer, beach(SHORE_VIEW, 100.0 + k * TP / 6.0)) for k in range(6)]
    return np.stack([lum for lum, _ in out]), out[0][1]


def _r2() -> float:
    return runup_r2(H0, TP, SLOPE)


def test_swash_runs_up_the_sand_and_the_shoreline_follows_it(swash_frames):
    """Swash (Holthuijsen, Waves in Oceanic and Coastal Waters, ch. 10; Stockdon et al. 2006 run-up
    R2 = 1.1 (0.35 β (H0 L0)^½ + ½ (H0 L0 (0.563 β² + 0.004))^½), 0.8 m here): over one wave period
    the sand between the still water line and half the run-up is covered and uncovered (its luminance
    changes by over 5 % on at least 30 % of those pixels), sand above 1.3 R2 never is (under 2 %).
    The highest sand reached in each image column (the run-up line) lies on average within 0.4-1.2
    R2 and varies along the shore (its spread over 3 % of R2): not the ruler-straight h = 0 line."""
    lum, xy = swash_frames
    z = elevation(xy)
    r2 = _r2()
    assert 0.4 < r2 < 1.2
    changed, reach = swash_reach(lum, z)  # the pixels the swash moves; per column, the highest sand it reaches
    low = (z > 0.03) & (z < 0.5 * r2)
    high = z > 1.3 * r2
    assert low.sum() > 500 and high.sum() > 500
    assert changed[low].mean() > 0.3, changed[low].mean()
    assert changed[high].mean() < 0.02, changed[high].mean()
    assert len(reach) > 100
    assert 0.4 * r2 < reach.mean() < 1.2 * r2, (reach.mean(), r2)
    assert reach.std() > 0.03 * r2, reach.std()


def test_wet_sand_is_darker_than_dry(swash_frames):
    """Wet sand reflects about 60 % of the light dry sand does (photographs of beaches; sand albedo
    0.35 dry, about 0.2 wet): below the run-up's reach (0.2-0.7 R2, median over the period) at most
    0.8 of the dry sand's luminance above 1.3 R2, in the same frame rows' range of distance."""
    lum, xy = swash_frames
    z = elevation(xy)
    r2 = _r2()
    median = np.median(lum, axis=0)
    wet = median[(z > 0.2 * r2) & (z < 0.7 * r2)]
    dry = median[(z > 1.3 * r2) & (z < 3.0 * r2)]
    assert wet.size > 200 and dry.size > 200
    assert np.median(wet) < 0.8 * np.median(dry), (np.median(wet), np.median(dry))


def test_breaking_crests_are_white_lines_that_move(renderer):
    """Breaker lines: in the surf zone (depth 0.3-2.5 m, where the waves break: H ≤ 0.78 h) white
    crests of broken water (Holthuijsen ch. 8; surf-zone photographs): at least 8 % of its pixels
    twice as bright as its unbroken water (the 30th percentile of its luminance), and they move:
    the white pixels half a period later overlap the first ones on under half of their union."""
    masks = []
    for t in (100.0, 100.0 + TP / 2.0):
        lum, xy = beach_frame(renderer, beach(SURF_VIEW, t))
        depth = -elevation(xy)
        surf = (depth > 0.3) & (depth < 2.5)
        assert surf.sum() > 500
        white = surf & (lum > 2.0 * np.percentile(lum[surf], 30))
        assert white.sum() > 0.08 * surf.sum(), white.sum() / surf.sum()
        masks.append(white)
    overlap = (masks[0] & masks[1]).sum() / (masks[0] | masks[1]).sum()
    assert overlap < 0.5, overlap
