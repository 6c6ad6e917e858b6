"""Sea foam on rendered pictures: whitecap coverage from any height, storm streaks along the wind,
fresh foam decaying over seconds, spindrift at Beaufort 9, no white band at hurricane winds.

Coverage is measured per pixel in the linear HDR target (before the tone map, whose curve would
weigh thin foam up) between the frame without whitecaps (threshold -1), the drawn frame and the frame
all white (threshold 10): (drawn - bare) / (white - bare) in luminance, over the sea."""

from __future__ import annotations

import numpy as np
import pytest

from igserver.quality.water_surf import foam_fraction, foam_scene, hdr_luminance, whitecap_coverage_seen
from igserver.water.surface import whitecap_coverage


@pytest.mark.parametrize("wind, height, pitch", [(9.4, 15.0, -3.0), (9.4, 300.0, -20.0), (22.6, 15.0, -3.0),
                                                  (22.6, 300.0, -20.0)])
def test_whitecap_coverage_from_the_bridge_and_the_air(renderer, wind, height, pitch):
    """Monahan & O'Muircheartaigh (1980), whitecap fraction W = 3.84e-6 U10^3.41 (0.8 % at Beaufort 5,
    16 % at Beaufort 9), from a bridge 15 m up looking at the horizon and from 300 m: within x1.5
    over four headings. From the bridge most of the sea is far away, where the mesh is coarse and
    its short waves faded: the foam used to be thresholded on the interpolated J there and the
    distant whitecaps vanished (0.27 % of the sea at Beaufort 5 from the bridge, measured); the mean
    foam cover is now interpolated and the faded waves' chance of foam kept (foam.glsl)."""
    coverage = whitecap_coverage_seen(renderer, wind, height, pitch)  # over four headings
    want = whitecap_coverage(wind)
    assert want / 1.5 < coverage < 1.5 * want, (coverage, want)


def _autocorrelation(c: np.ndarray) -> np.ndarray:
    d = c - c.mean()
    f = np.fft.fft2(d)
    acf = np.real(np.fft.ifft2(f * np.conj(f)))
    return acf / acf[0, 0]


def _length(profile: np.ndarray) -> float:
    """Lag (pixels) where an autocorrelation profile falls to 1/e."""
    below = np.nonzero(profile < 1.0 / np.e)[0]
    return float(below[0]) if len(below) else float(len(profile))


def test_storm_foam_lies_in_streaks_along_the_wind(renderer):
    """Beaufort 8-10 (WMO sea-state photographs; Holthuijsen, Waves in Oceanic and Coastal Waters,
    the Beaufort table): "dense streaks of foam along the direction of the wind", longer as the wind
    rises. Looking straight down from 300 m with the wind along the image's vertical (wind from 250°,
    heading 70°, about 0.6 m a pixel): the foam's fine structure (less its blur over 4 pixels) varies
    at least 2x as much (squared gradient) across the wind as along it (measured 2.9 at Beaufort 9,
    1.4 with round whitecap patches), and its correlation length along the wind is longer at 30 m/s
    than at 20 m/s."""
    from scipy.ndimage import gaussian_filter

    along_lengths = []
    for wind in (20.0, 30.0):
        c, sea = foam_fraction(renderer, foam_scene(wind, 300.0, -89.0, heading=70.0, size=(256, 256)))
        assert sea.all()
        fine = c - gaussian_filter(c, 4.0, mode="wrap")
        along, across = np.mean(np.diff(fine, axis=0) ** 2), np.mean(np.diff(fine, axis=1) ** 2)
        assert across > 2.0 * along, (across, along)
        along_lengths.append(_length(_autocorrelation(c)[:128, 0]))
    assert along_lengths[1] > along_lengths[0], along_lengths


def test_fresh_foam_fades_over_seconds(renderer):
    """Whitecaps fade with an e-folding time of about 3.5 s (Monahan 1971, 3.53 s): the foam stays on
    the water that broke and thins, white, then grey-green. From 300 m looking down at Beaufort 9, the
    pixels fully white at t (fresh foam) are on average still foamy 1.5 s later but less so (measured
    0.48), less again after 4 s, and after 8 s back near the sea's mean (the next crest has not come)."""
    frames = [foam_fraction(renderer, foam_scene(22.6, 300.0, -89.0, heading=70.0, t=100.0 + dt, size=(192, 192)))[0]
              for dt in (0.0, 1.5, 4.0, 8.0)]
    fresh = frames[0] > 0.95
    assert fresh.mean() > 0.02
    means = [float(f[fresh].mean()) for f in frames]
    assert means[0] > means[1] > means[2], means
    assert 0.3 < means[1] < 0.9, means
    assert max(means[2], means[3]) < 0.5 * means[1], means


def test_spindrift_whitens_beaufort_9_crests_not_beaufort_5(renderer, monkeypatch):
    """Beaufort 8: "edges of crests begin to break into spindrift"; Beaufort 9: "spray may affect
    visibility". Bridge view: the frame with the spray against the frame with it turned off differs
    on at least 2 % of the sea at Beaufort 9 (brighter), and not at all at Beaufort 5."""
    from igserver.render.water import foam

    def brighter(wind):
        scene = foam_scene(wind, 15.0, -3.0, heading=70.0)
        with_spray = hdr_luminance(renderer, scene)
        monkeypatch.setattr(foam, "spray_strength", lambda w: 0.0)
        without = hdr_luminance(renderer, scene)
        monkeypatch.undo()
        return with_spray - without

    storm = brighter(22.6)
    assert storm.min() >= -1e-3
    assert np.mean(storm > 0.02 * np.median(np.abs(storm) + 1e-6) + 1e-3) > 0.02
    assert np.abs(brighter(9.4)).max() == 0.0


def test_no_white_band_at_hurricane_winds_from_the_bridge(renderer):
    """At 80 m/s (Monahan's fraction held at one half: whitecap_coverage) no band of rows of the sea
    seen from the bridge may be solid white (the faceted white band that covered the view at 30 m/s):
    every row's mean foam fraction stays under 0.85."""
    c, sea = foam_fraction(renderer, foam_scene(80.0, 15.0, -3.0))
    rows = [float(c[i][sea[i]].mean()) for i in range(c.shape[0]) if sea[i].mean() > 0.9]
    assert max(rows) < 0.85, max(rows)


def _far_quarter(sea: np.ndarray) -> np.ndarray:
    """The rows of the upper quarter of the sea's rows (the far sea seen from a bridge)."""
    rows = np.nonzero(sea.any(axis=1))[0]
    far = np.zeros_like(sea)
    far[rows.min(): rows.min() + (rows.max() - rows.min()) // 4] = True
    return far & sea


def test_white_horses_reach_the_horizon_at_beaufort_5(renderer):
    """Beaufort 5 ("moderate waves, many white horses"; Monahan & O'Muircheartaigh 1980: W = 0.8 %) from a
    bridge 15 m up: far off, where a pixel spans patch cells, the foam was its mean, an even grey veil,
    and the frame showed a few whitecaps, all near. A sea's whitecaps are sparse (W / a of them per m²,
    a their area), so the far sea shows them as scattered dots (foam_streaks.glsl foam_dots). In the
    far quarter of the sea at 320x180, separate whitecaps (foam fraction > 0.05, connected), four
    headings: 23, 16, 20, 13 before (72), 58, 26, 31, 28 now (143); the coverage is unchanged (the
    test above)."""
    from scipy import ndimage

    counts = []
    for heading in (30.0, 120.0, 210.0, 300.0):
        c, sea = foam_fraction(renderer, foam_scene(9.4, 15.0, -3.0, heading=heading, size=(320, 180)))
        counts.append(ndimage.label((c > 0.05) & _far_quarter(sea))[1])
    assert min(counts) >= 20 and sum(counts) >= 110, counts


def test_far_whitecaps_do_not_twinkle(renderer):
    """The far whitecaps' dots fade in and out as the waves move the foam's mean and as each cell's
    whitecap ages (foam_streaks.glsl foam_dots), instead of popping: from a still bridge at 30 frames
    a second, under 1 % of the far quarter's pixels change by more than 32 levels from one frame to
    the next (0.2 % measured at 640x360)."""
    frames = [renderer.render(foam_scene(9.4, 15.0, -3.0, t=100.0 + i / 30.0, size=(640, 360))).rgba[..., :3]
              .astype(np.float64) for i in range(3)]
    _, sea = foam_fraction(renderer, foam_scene(9.4, 15.0, -3.0, t=100.0, size=(640, 360)))
    far = _far_quarter(sea)
    changed = [np.mean(np.abs(frames[i + 1] - frames[i]).max(axis=-1)[far] > 32.0) for i in range(2)]
    assert max(changed) < 0.01, changed


def test_a_sea_too_calm_for_whitecaps_leaves_the_foam_out(renderer, monkeypatch):
    """Below Beaufort 3 (3.4 m/s, "crests begin to break", WMO) crests do not break: the water program
    leaves the foam's code out (foam.py foam_drawn; llvmpipe ran it on every pixel, a fifth of a calm
    sea's water pass). At 1 m/s (Monahan & O'Muircheartaigh's fit: W = 4e-6) the picture is the one
    drawn with the foam within a level but in under 0.01 % of its pixels (2 of 57,600 measured); a
    sea at 4 m/s keeps its foam."""
    import igserver.render.water.water as water_module

    water = renderer.graph.passes["water"]
    calm = foam_scene(1.0, 15.0, -3.0, size=(320, 180))
    without = renderer.render(calm).rgba.astype(int)
    assert water.stats["foam"] is False
    monkeypatch.setattr(water_module, "foam_drawn", lambda *args: True)
    with_foam = renderer.render(calm).rgba.astype(int)
    assert water.stats["foam"] is True
    assert np.mean(np.abs(with_foam - without).max(axis=-1) > 1) < 1e-4
    monkeypatch.undo()
    renderer.render(foam_scene(4.0, 15.0, -3.0, size=(320, 180)))
    assert water.stats["foam"] is True


def test_without_foam_the_streak_and_dot_choices_are_one_program(renderer):
    """The streaks' and the dots' variants are parts of the foam: a sea drawn without it compiles one
    program whatever the frame's values would pick for them (each would be another compile, the
    same code), and a sea with foam keeps them apart."""
    water = renderer.graph.passes["water"]
    renderer.ctx  # made current: the programs compile on it, whatever context a test used last
    rows = {"u_foam_octaves": (0.5, 0.5, 0.7)}  # wind rows: no dots
    calm = {water._program(False, foam=False, foam_streaks=s, values=v) for s in (0, 1, 2) for v in ({}, rows)}
    assert len(calm) == 1
    foamy = {water._program(False, foam=True, foam_streaks=s, values=v) for s in (0, 1, 2) for v in ({}, rows)}
    assert len(foamy) == 6
