"""Storm foam streaks lie along the wind on the sea, at any distance: their orientation on pictures.

Beaufort 8-10 (WMO sea-state photographs; the Met Office Beaufort table): "foam is blown in
well-marked streaks along the direction of the wind" (8), "dense streaks of foam" (9); seen from the
air the streaks are parallel lines along the wind. The wind rows are measured alone: the frame with
them and no whitecaps (J threshold -1) less the frame with neither, over the all-white frame less
it (linear HDR luminance). The orientation is the structure tensor's (the squared gradient's mean
outer product, Bigun & Granlund 1987): its weak axis is the streaks' direction, its coherence
(l1 - l2) / (l1 + l2) how much one direction dominates (0: no direction, a veil; 1: parallel lines)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from igserver.quality.water_surf import foam_fraction, foam_scene, hdr_luminance


def wind_rows(renderer, scene, monkeypatch) -> tuple[np.ndarray, np.ndarray]:
    """Per pixel the wind rows' foam fraction and the sea mask."""
    from igserver.render.water import foam

    water = renderer.graph.passes["water"]
    try:
        water.foam_threshold = -1.0  # no whitecaps: the wind rows only
        rows = hdr_luminance(renderer, scene)
        water.foam_threshold = 10.0
        white = hdr_luminance(renderer, scene)
        water.foam_threshold = -1.0
        monkeypatch.setattr(foam, "streak_opacity", lambda wind: 0.0)
        bare = hdr_luminance(renderer, scene)
    finally:
        water.foam_threshold = None
        monkeypatch.undo()
    span = white - bare
    sea = span > 0.05 * np.median(span[span > 0])
    return np.clip((rows - bare) / np.where(sea, span, 1.0), 0.0, 1.0), sea


def streak_direction(c: np.ndarray, mask: np.ndarray) -> tuple[float, float]:
    """The dominant direction of the pattern c over mask (degrees from the image's +x toward its +y,
    rows going down, in [0, 180)) and the structure tensor's coherence. The gradients are taken on c
    smoothed over a pixel: on the raw pixels lines 1-3 px wide read up to 7 degrees nearer the
    diagonal (pixel-grid bias, measured)."""
    from scipy.ndimage import gaussian_filter

    gy, gx = np.gradient(gaussian_filter(c, 1.0))
    w = mask[1:-1, 1:-1]
    gx, gy = gx[1:-1, 1:-1][w], gy[1:-1, 1:-1][w]
    jxx, jyy, jxy = float(np.mean(gx * gx)), float(np.mean(gy * gy)), float(np.mean(gx * gy))
    across = 0.5 * math.degrees(math.atan2(2.0 * jxy, jxx - jyy))  # the gradients' direction
    coherence = math.hypot(jxx - jyy, 2.0 * jxy) / max(jxx + jyy, 1e-30)
    return (across + 90.0) % 180.0, coherence


def angle_between(a: float, b: float) -> float:
    d = abs(a - b) % 180.0
    return min(d, 180.0 - d)


@pytest.mark.parametrize("wind", [22.6, 30.0])
def test_wind_rows_seen_from_300_m_lie_along_the_wind(renderer, monkeypatch, wind):
    """Straight down from 300 m (about 1.2 m a pixel) with the wind 30 degrees off the image's
    vertical (from 250 degrees, heading 100): the wind rows' dominant direction within 10 degrees of the
    wind, coherence at least 0.5 (parallel lines). Their thin streaks (1.5 m across) are below a
    pixel there: the streak noise faded to its mean and the rows were a grey veil crossed by the
    crest-long bands of the sea's J (83 degrees off the wind, coherence 0.05 and 0.12, measured); now
    the wider rows they bunch into remain (2 degrees off, coherence 0.97 and 0.98)."""
    c, sea = wind_rows(renderer, foam_scene(wind, 300.0, -89.0, heading=100.0, size=(256, 256)), monkeypatch)
    assert sea.all()
    assert c.mean() > 0.01  # the rows are there
    direction, coherence = streak_direction(c, sea)
    # the wind blows toward 70 degrees, 30 degrees left of the view's 100 (up): up-left on the image
    wind_on_image = math.degrees(math.atan2(-math.cos(math.radians(30.0)), -math.sin(math.radians(30.0)))) % 180.0
    assert angle_between(direction, wind_on_image) < 10.0, (direction, wind_on_image, coherence)
    assert coherence > 0.5, coherence


def test_wind_rows_run_sideways_across_the_wind_from_the_bridge(renderer, monkeypatch):
    """From a bridge 15 m up looking across the wind (heading 160, the wind toward 70: from the right
    to the left), streaks along the wind lie in the sea plane and run sideways on the picture, down
    to the horizon: the lower half's wind rows (the near sea) and the band above it (100 m to 1 km)
    are horizontal within 10 degrees, coherence at least 0.6 (measured 5 and 3 degrees, 0.96 and
    0.97; the thin streaks alone drew them so too)."""
    c, sea = wind_rows(renderer, foam_scene(22.6, 15.0, -3.0, heading=160.0, size=(320, 180)), monkeypatch)
    rows = np.nonzero(sea.mean(axis=1) > 0.99)[0]
    top = int(rows[0])
    near, far = np.zeros_like(sea), np.zeros_like(sea)
    near[(top + 180) // 2:] = True
    far[top + 4:(top + 180) // 2] = True
    for part in (near & sea, far & sea):
        assert c[part].mean() > 0.005
        direction, coherence = streak_direction(c, part)
        assert angle_between(direction, 0.0) < 10.0, (direction, coherence)
        assert coherence > 0.6, coherence


def test_storm_streaks_stay_on_the_sea_when_the_eye_moves(renderer):
    """The foam is fixed on the sea (drifting only with the surface): seen straight down from 40 m at
    22.6 m/s, a camera moved by a whole number of pixels' ground size at the same sim_time sees the
    same foam shifted by as many pixels (mean |difference| of the foam fraction over the overlap under
    half the foam's mean; 0.1-0.3 of it measured: the mesh's blocks move with the eye). The storm
    streaks' meander was anchored to the camera, not the sea, and moved the streaks with the eye (mean
    |difference| 1.2-1.4 times the foam's mean)."""
    size = 256
    pixel = 2.0 * 40.0 * math.tan(math.radians(55.0 / 2.0)) / size  # m a pixel spans on the sea
    k = 12

    def foam(x: float, y: float) -> np.ndarray:
        scene = foam_scene(22.6, 40.0, -90.0, heading=0.0, size=(size, size))
        scene = scene.model_copy(update={"camera": scene.camera.model_copy(update={"position": (x, y, 40.0)})})
        return foam_fraction(renderer, scene)[0]

    still = foam(0.0, 0.0)
    east, north = foam(k * pixel, 0.0), foam(0.0, k * pixel)
    inner = (slice(16, -16), slice(16, -16))
    for a, b in ((still[:, k:], east[:, :-k]), (still[:-k, :], north[k:, :])):
        assert a[inner].mean() > 0.01
        assert np.abs(a[inner] - b[inner]).mean() < 0.5 * a[inner].mean(), (np.abs(a - b).mean(), a.mean())


def test_octave_scales_agree_between_python_and_glsl():
    """foam.py FOAM_OCTAVE_SCALE (the camera's noise coordinates per octave) and foam_streaks.glsl's
    FOAM_OCTAVE_SCALE_1, _2 (the lookups) are one table written twice: they must agree."""
    import re
    from importlib.resources import files

    from igserver.render.water.foam import FOAM_OCTAVE_SCALE

    glsl = (files("igserver.render.water") / "foam_streaks.glsl").read_text()
    for i in (1, 2):
        x, y = re.search(rf"FOAM_OCTAVE_SCALE_{i} = vec2\(([\d.]+), ([\d.]+)\)", glsl).groups()
        assert (float(x), float(y)) == FOAM_OCTAVE_SCALE[i]


def test_whitecap_patches_scale_with_the_waves():
    """A whitecap spans part of its breaking crest: its noise cell is FOAM_PATCH_SIZE from Hs 6 m, in
    proportion below, at least a fifth of it (the beach's 1.7 m surf drew blobs 10 m long)."""
    from igserver.render.water.foam import FOAM_PATCH_SIZE, whitecap_patch_size

    assert whitecap_patch_size(8.0) == FOAM_PATCH_SIZE == whitecap_patch_size(6.0)
    assert whitecap_patch_size(3.0) == pytest.approx((5.0, 1.5))
    assert whitecap_patch_size(0.1) == pytest.approx((2.0, 0.6))
