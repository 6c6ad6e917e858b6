"""Rain and snow in the picture (tiny frames on llvmpipe): streak orientation follows the wind
(structure tensor of the rain's own contribution against the projected particle motion), density
follows the rate, no empty slab between tiles, a camera at 250 m/s does not smear, the scene hides
the rain behind it, and extreme inputs stay finite."""

import math

import numpy as np
import pytest

from igserver.photometry import LUMA
from igserver.render.camera import make_view
from igserver.render.precip.particles import PRESETS
from igserver.scene import apply_patch
from igserver.weather import fall_speed

from helpers import tiny

W, H = 160, 90
# Daylight, looking level at the horizon with no ground: the rain is drawn over a smooth sky, so the
# picture's gradients are the streaks'. A long exposure (50 ms) gives streaks of ~10 px.
BASE = {
    "camera": {"position": [0.0, 0.0, 10.0], "heading": 0.0, "pitch": 0.0, "fov_y": 40.0, "exposure_ev": 12.0},
    "ground": {"enabled": False},
    "time": {"sun_override": {"elevation": 35.0, "azimuth": 180.0}, "sim_time": 50.0},
    "weather": {"wind_speed": 0.0, "precipitation": {"type": "rain", "rate": 20.0, "streak_time": 0.05,
                                                  # streaks only: the rain's fog is tested in test_atmosphere_light
                                                  "lowers_visibility": False}},
}


def scene(patch=None):
    return apply_patch(tiny(BASE, W, H), patch or {})


def contribution(renderer, s):
    """Pre-exposed luminance the precipitation adds (or hides): frame minus the same frame dry."""
    def lum(sc):
        renderer.render(sc)
        hdr = renderer.read_hdr()
        assert np.isfinite(hdr).all(), "NaN/Inf in the HDR target"
        return hdr[..., :3] @ LUMA
    dry = apply_patch(s, {"weather": {"precipitation": {"type": "none"}}})
    return lum(s) - lum(dry)


def streak_angle(image):
    """Dominant streak orientation in degrees from the screen's vertical (positive when the lower end
    lies to the right) and the anisotropy (0 isotropic .. 1 all parallel), from the picture's
    autocorrelation: along the streaks a pixel correlates with its neighbours 3-6 px away, across
    them it does not. (A gradient structure tensor is biased toward the pixel axes by the staircase
    of aliased thin lines; the autocorrelation is not.)"""
    img = image - image.mean()
    f = np.fft.fft2(img)
    ac = np.fft.fftshift(np.real(np.fft.ifft2(f * np.conj(f))))
    ac /= ac.max()
    cy, cx = np.array(ac.shape) // 2
    angles = np.radians(np.arange(-90.0, 90.0, 1.0))
    radii = np.array([3.0, 4.0, 5.0, 6.0])
    # Direction at angle a from vertical-down: (x, y) = (sin a, cos a), rows going down.
    xs = cx + np.outer(np.sin(angles), radii)
    ys = cy + np.outer(np.cos(angles), radii)
    x0, y0 = np.floor(xs).astype(int), np.floor(ys).astype(int)
    fx, fy = xs - x0, ys - y0
    sample = (ac[y0, x0] * (1 - fx) * (1 - fy) + ac[y0, x0 + 1] * fx * (1 - fy)
              + ac[y0 + 1, x0] * (1 - fx) * fy + ac[y0 + 1, x0 + 1] * fx * fy).mean(axis=1)
    best = int(np.argmax(sample))
    return float(np.degrees(angles[best])), float((sample.max() - sample.min()) / sample.max())


def expected_angle(s):
    """Screen angle of the particles' motion at the image centre (heading north: x right, z up),
    averaged with the weight each streak has in the picture: its coverage ~ D^2 (big drops fall
    faster, so the picture's streaks are steeper than the plain mean motion)."""
    frame_particles = _particles(s)
    weight = frame_particles.diameters**2
    v = (frame_particles.streaks * weight[:, None]).sum(axis=0)
    return math.degrees(math.atan2(v[0], -v[2]))


def _particles(s):
    from igserver.render.precip.particles import ParticlePool, particle_frame
    return particle_frame(s, make_view(s.camera), PRESETS[s.quality.preset], ParticlePool())


@pytest.mark.parametrize("wind", [(0.0, 270.0), (6.0, 270.0), (6.0, 90.0), (12.0, 270.0)])
def test_streak_direction_follows_the_wind(renderer, wind):
    speed, direction = wind
    s = scene({"weather": {"wind_speed": speed, "wind_direction": direction}})
    angle, anisotropy = streak_angle(contribution(renderer, s))
    want = expected_angle(s)
    # The physics: the streak leans by atan(u / v_fall) from the vertical, v_fall 4-9 m/s, so 6 m/s
    # from the west leans 30-56 deg to the right (east is right when facing north).
    if speed > 0:
        lean = np.degrees(np.arctan2(speed, np.array([fall_speed("rain", 6.0), fall_speed("rain", 1.0)])))
        assert lean[0] - 1 <= abs(want) <= lean[1] + 1
        assert math.copysign(1, want) == (1 if direction == 270.0 else -1)
    # Tolerance 6 deg: the perspective turns a direction across a 40 deg field by up to ~5 deg at
    # the edges, and each streak's own fall speed scatters around the mean.
    assert abs(angle - want) < 6.0, (angle, want)
    assert anisotropy > 0.3, "streaks should be parallel lines, not isotropic noise"


def _visible_optical_depth(rate):
    """Marshall-Palmer, independent of the renderer: integral over the drawn 1-6 mm drops of
    D^2 N0 exp(-Lambda D) dD (the mean coverage of the streaks is this times a constant)."""
    lam = 4.1 * rate**-0.21
    d = np.linspace(1.0, 6.0, 2001)
    return np.trapezoid(d**2 * 8000.0 * np.exp(-lam * d), d)


def test_density_follows_the_rate(renderer):
    rates = (1.0, 5.0, 25.0)
    covered = [np.mean(np.abs(contribution(renderer, scene({"weather": {"precipitation": {"rate": r}}}))))
               for r in rates]
    # Coverage ratios follow the visible drops' optical depth (x5.4 from 1 to 5 mm/h, x4.1 from 5 to
    # 25); within a factor 1.6: a 160x90 frame holds a few hundred streaks (sampling noise) and the
    # near-camera fade and the clamp of opacity at 1 bend it a little.
    for (r0, c0), (r1, c1) in zip(zip(rates, covered), zip(rates[1:], covered[1:])):
        want = _visible_optical_depth(r1) / _visible_optical_depth(r0)
        assert want / 1.6 < c1 / c0 < want * 1.6, (covered, want)


def test_no_empty_slab_between_tiles(renderer):
    """Coverage over a 4 x 8 grid of screen blocks: every block gets rain (a gap at the cube faces
    or between LOD levels would leave a block or a line of blocks empty)."""
    c = np.abs(contribution(renderer, scene({"weather": {"precipitation": {"rate": 25.0}}})))
    blocks = c[: H // 4 * 4, : W // 8 * 8].reshape(4, H // 4, 8, W // 8).mean(axis=(1, 3))
    # Each block holds ~20 streaks at this rate, so sampling alone keeps blocks within ~3x of the median.
    assert blocks.min() > 0.25 * np.median(blocks), blocks


def test_camera_at_250_m_per_s_does_not_smear(renderer):
    """Frames of a camera flying north at 250 m/s (60 Hz) show the same streaks as a parked
    camera's: same orientation and anisotropy. Streaks drawn from the camera-relative
    motion would be ~4 m long lines radiating from the centre of the view."""
    parked = [streak_angle(contribution(renderer, scene({"time": {"sim_time": 50.0 + i / 60}}))) for i in range(2)]
    flying = []
    for i in range(2):
        s = scene({"time": {"sim_time": 50.0 + i / 60}, "camera": {"position": [0.0, 250.0 * i / 60, 10.0]}})
        c = contribution(renderer, s)
        flying.append((*streak_angle(c), np.mean(np.abs(c))))
    for (a_p, an_p), (a_f, an_f, _) in zip(parked, flying):
        assert abs(a_f - a_p) < 6.0 and abs(an_f - an_p) < 0.15
    # Rain falling straight down seen from a still or moving camera: vertical streaks.
    assert all(abs(a) < 6.0 for a, _, _ in flying)


def test_the_scene_hides_the_rain_behind_it(renderer):
    # A pillar 2 m ahead, 1 m wide: it covers the middle ~30 % of the columns (x 48..112).
    s = scene({"entities": [{"id": "wall", "model": "box", "position": [0.0, 2.0, 7.0], "scale": [1.0, 0.2, 6.0]}]})
    c = np.abs(contribution(renderer, s))
    wall, sky = c[:, 65:95], np.concatenate([c[:, :30], c[:, 130:]], axis=1)
    # In front of the wall lies 2 m of rain (with the near fade) against the sky's 30 m of streaks.
    assert wall.mean() < 0.35 * sky.mean(), (wall.mean(), sky.mean())


@pytest.mark.parametrize("patch", [
    {"weather": {"wind_speed": 40.0, "precipitation": {"type": "rain", "rate": 200.0}}},
    {"weather": {"wind_speed": 40.0, "precipitation": {"type": "snow", "rate": 200.0}}},
    {"time": {"sim_time": 1e9}, "camera": {"position": [1e6, -1e6, 10.0]}},
])
def test_extremes_stay_finite_and_bounded(renderer, patch):
    s = scene(patch)
    c = contribution(renderer, s)
    assert np.abs(c).mean() > 0.0
    assert renderer.graph.passes["precip"].stats["streaks"] <= PRESETS["medium"].max_streaks


def test_snow_in_the_picture_is_slower_and_whiter_than_rain(renderer):
    snow = scene({"weather": {"precipitation": {"type": "snow", "rate": 2.0}}})
    c = contribution(renderer, snow)
    assert np.isfinite(c).all() and np.abs(c).mean() > 0.0
    # Flakes 0.5-1.5 m/s over 50 ms: streaks 2.5-7.5 cm vs rain's 20-45 cm; at the same spots the
    # vertical extent of the snow marks is shorter: measured by the vertical autocorrelation length.
    def vertical_corr(img):
        img = img - img.mean()
        return (img[1:] * img[:-1]).sum() / (img * img).sum()
    rain_c = contribution(renderer, scene({"weather": {"precipitation": {"rate": 20.0}}}))
    assert vertical_corr(c) < vertical_corr(rain_c)


def test_a_searchlight_lights_the_rain_in_its_beam(renderer):
    """At night a spot light pointing straight down 8 m ahead lights the drops inside its cone
    (the beam shows as a bright column of streaks); the rest of the rain stays dark."""
    night = scene({
        "time": {"sun_override": {"elevation": -30.0, "azimuth": 180.0}},
        "camera": {"exposure_ev": 2.0},
        "lights": [{"id": "searchlight", "type": "spot", "position": [0.0, 8.0, 16.0], "pitch": -90.0,
                    "intensity": 2e5, "range": 200.0, "cone_inner": 8.0, "cone_outer": 12.0}],
    })
    c = contribution(renderer, night)
    # The cone is ~1.3 m wide at the camera's height, 8 m away: +-5 deg, ~+-12 px about the centre
    # column of a 40 deg (90 px) view; outside +-35 px no drop is in the beam.
    beam = c[:, 72:88].mean()
    outside = np.concatenate([c[:, :40], c[:, 120:]], axis=1).mean()
    assert beam > 0.0 and beam > 10.0 * max(outside, 0.0), (beam, outside)
