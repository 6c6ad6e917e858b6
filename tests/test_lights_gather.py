"""The frame's point and spot lights (igserver/render/lights.py) without GL: the flicker's spectrum shape and
statistics as its docstring promises them, host lights as the scene states them, which lights reach the
frame and in what order, and the uniform layout the shaders read."""

from __future__ import annotations

import math

import numpy as np
import pytest

from igserver.render.camera import make_view
from igserver.render.lights import PointLight, flicker_gain, gather_lights, host_lights, light_uniforms
from igserver.scene import Scene

F = 1.5  # Hz, a flicker's peak frequency (any positive value: everything below is relative to it)
CYCLES = 400  # of the peak frequency: partials 0.04 apart in ln f are 16 FFT bins apart, well resolved


def _power_spectrum(seed: int, amplitude: float = 0.2):
    rate = 20.0 * F
    t = np.arange(0.0, CYCLES / F, 1.0 / rate)
    gain = flicker_gain(F, amplitude, seed, t)
    window = np.hanning(len(t))
    power = np.abs(np.fft.rfft((gain - gain.mean()) * window)) ** 2
    return np.fft.rfftfreq(len(t), 1.0 / rate), power, gain


def _fraction_within(freqs, power, log_half_width: float) -> float:
    band = (freqs > 0) & (np.abs(np.log(np.maximum(freqs, 1e-12) / F)) <= log_half_width)
    return float(power[band].sum() / power.sum())


@pytest.mark.parametrize("seed", range(6))
def test_flicker_power_is_gaussian_in_log_frequency(seed):
    """Weights Gaussian in ln f of width 0.25 put the power (weight²) in a Gaussian of width 0.177: 95.2 %
    of it within ln f ± 0.35 for a continuous spectrum; the 13 partials 0.1 apart hold 95.6 % within it
    (those at |ln f| <= 0.33 against the rest), and the seeded jitter (± 0.03) and weight factors (0.85..1)
    move that within 0.935..0.975: bounds 0.92..0.985. A narrower or flat weighting leaves them
    (width 0.144: 99.96 %; flat: ~55 %). The peak partial alone holds 1/Σw² = 22.6 % of the power, 28.8 %
    at most with the weight factors: bounds 0.2..0.33 (a doubled peak holds 54 %)."""
    freqs, power, _ = _power_spectrum(seed)
    assert 0.92 < _fraction_within(freqs, power, 0.35) < 0.985
    assert 0.2 < _fraction_within(freqs, power, 0.04) < 0.33


@pytest.mark.parametrize("seed", range(4))
def test_flicker_relative_rms_is_amplitude_over_root_two(seed):
    """Unit-power partials: the gain's RMS variation is amplitude/√2 (a sum of sinusoids whose weights have
    unit L2 norm). Over 400 peak cycles the cross terms of partials at least 0.04 apart in ln f average to
    under 1/(2π·0.04·400) = 1 % each: 3 %."""
    _, _, gain = _power_spectrum(seed, amplitude=0.2)  # 0.2: the gain never clips at 0 (|signal| < 3)
    rms = float(np.sqrt(np.mean((gain - 1.0) ** 2)))
    assert rms == pytest.approx(0.2 / math.sqrt(2.0), rel=0.03)


def test_flicker_phases_are_uniform_and_independent():
    """At t = 0 the signal is Σ wᵢ sin φᵢ: with independent uniform phases its mean over seeds is 0 and its
    variance Σwᵢ²/2 = 1/2. Over 400 seeds (fixed: the test is deterministic) the mean has a standard error
    of 0.035 and the variance 0.035 (relative √(2/400)): bounds ±0.15 and 0.38..0.62 (over 3.4 σ). Phases
    shared by all partials give variance Σwᵢ²... ≈ 4.4; phases in part of the circle a mean of 0.26 or more."""
    amplitude = 1e-3  # small: the gain is 1 + amplitude * signal, never clipped
    signal = np.array([flicker_gain(F, amplitude, seed, 0.0) - 1.0 for seed in range(400)]) / amplitude
    assert abs(signal.mean()) < 0.15
    assert 0.38 < signal.var() < 0.62


def test_flicker_gain_of_a_time_is_a_float():
    assert isinstance(flicker_gain(F, 0.3, 1, 12.5), float)
    assert flicker_gain(F, 0.3, 1, np.array([12.5, 13.0])).shape == (2,)


def _scene(lights: list[dict], **extra) -> Scene:
    return Scene.model_validate({"camera": {"position": [0, 0, 2], "heading": 0, "pitch": 0}, "lights": lights,
                                 **extra})


def test_host_light_is_the_scene_light_times_its_flicker():
    flicker = {"enabled": True, "frequency": 2.0, "amplitude": 0.5, "seed": 7}
    scene = _scene([{"id": "a", "position": [3, 40, 5], "color": [1.0, 0.5, 0.25], "intensity": 800,
                     "range": 60, "flicker": flicker}], time={"sim_time": 3.3})
    (light,) = host_lights(scene)
    gain = flicker_gain(2.0, 0.5, 7, 3.3)
    assert abs(gain - 1.0) > 0.05  # the case tells multiplying by the flicker from dividing or ignoring it
    assert np.allclose(light.color, np.array([1.0, 0.5, 0.25]) * 800 * gain, rtol=1e-12)
    assert np.array_equal(light.position, [3.0, 40.0, 5.0]) and light.position.dtype == np.float64
    assert light.range == 60 and light.spot_dir is None
    # seeded: the same scene gives the same light, another seed another one
    assert np.array_equal(host_lights(scene)[0].color, light.color)
    other = _scene([{"id": "a", "position": [3, 40, 5], "color": [1.0, 0.5, 0.25], "intensity": 800, "range": 60,
                     "flicker": {**flicker, "seed": 8}}], time={"sim_time": 3.3})
    assert not np.allclose(host_lights(other)[0].color, light.color)


def test_spot_light_points_where_heading_and_pitch_say():
    scene = _scene([{"id": "s", "type": "spot", "position": [1, 2, 3], "heading": 90, "pitch": -30,
                     "cone_inner": 10, "cone_outer": 25, "intensity": 500, "range": 80}])
    (spot,) = host_lights(scene)
    # heading 90 = east, 30 deg down: (cos 30, 0, -sin 30) in ENU
    assert np.allclose(spot.spot_dir, [math.cos(math.radians(30)), 0.0, -0.5], atol=1e-12)
    assert spot.cos_inner == pytest.approx(math.cos(math.radians(10)))
    assert spot.cos_outer == pytest.approx(math.cos(math.radians(25)))
    assert np.array_equal(spot.position, [1.0, 2.0, 3.0]) and spot.range == 80
    assert np.allclose(spot.color, np.array([1.0, 0.85, 0.6]) * 500)


def _view(scene):
    return make_view(scene.camera)


def test_dark_lights_are_left_out_and_dim_ones_kept():
    """A light of zero intensity adds nothing and takes no slot; one of 0.5 cd is dim, not absent."""
    scene = _scene([{"id": "off", "position": [0, 20, 2], "intensity": 0.0},
                    {"id": "dim", "position": [0, 30, 2], "intensity": 0.5, "color": [1, 1, 1]}])
    lights = gather_lights(scene, _view(scene), 8)
    assert len(lights) == 1 and lights[0].color.max() == pytest.approx(0.5)


def test_lights_are_ranked_by_illuminance_at_the_camera():
    """Importance is I/d² (the illuminance a light gives at the camera), counted from 1 m: a dim light near
    the camera beats a bright one far away, and inside 1 m distance no longer raises it."""
    scene = _scene([{"id": "far", "position": [0, 100, 2], "intensity": 5000, "color": [1, 1, 1]},  # 0.5 lx
                    {"id": "near", "position": [0, 5, 2], "intensity": 100, "color": [1, 1, 1]}])  # 4 lx
    assert gather_lights(scene, _view(scene), 1)[0].color.max() == pytest.approx(100)
    assert [l.color.max() for l in gather_lights(scene, _view(scene), 2)] == pytest.approx([100, 5000])
    # 0.5 m away counts as 1 m: 1.0 cd → 1 lx; 1.3 m away: 1.5 cd → 0.89 lx; the nearer one ranks first
    close = _scene([{"id": "a", "position": [0, 0.5, 2], "intensity": 1.0, "color": [1, 1, 1]},
                    {"id": "b", "position": [0, 1.3, 2], "intensity": 1.5, "color": [1, 1, 1]}])
    assert gather_lights(close, _view(close), 1)[0].color.max() == pytest.approx(1.0)


def test_light_uniforms_layout():
    """What the shaders read (common/lights.glsl): camera-relative position and range, colour and a spot
    flag, spot axis and cos(outer), cos(inner) kept above cos(outer) so the smoothstep has width."""
    scene = _scene([])
    view = _view(scene)
    point = PointLight(np.array([10.0, 20.0, 5.0]), np.array([3.0, 2.0, 1.0]), 50.0)
    spot = PointLight(np.array([0.0, 5.0, 2.0]), np.array([1.0, 1.0, 1.0]), 30.0,
                      np.array([0.0, 1.0, 0.0]), math.cos(math.radians(20)), math.cos(math.radians(20)))
    u = light_uniforms([point, spot], view, 4)
    assert u["u_light_count"] == 2
    pos = np.frombuffer(u["u_light_pos"], np.float32).reshape(4, 4)
    col = np.frombuffer(u["u_light_color"], np.float32).reshape(4, 4)
    dirs = np.frombuffer(u["u_light_dir"], np.float32).reshape(4, 4)
    cos_inner = np.frombuffer(u["u_light_cos_inner"], np.float32)
    assert np.allclose(pos[0], [10.0, 20.0, 3.0, 50.0]) and np.allclose(pos[1], [0.0, 5.0, 0.0, 30.0])
    assert np.allclose(col[0], [3.0, 2.0, 1.0, 0.0]) and np.allclose(col[1], [1.0, 1.0, 1.0, 1.0])
    assert np.allclose(dirs[0], 0.0) and np.allclose(dirs[1], [0.0, 1.0, 0.0, math.cos(math.radians(20))])
    assert cos_inner[0] == 1.0 and cos_inner[1] == pytest.approx(math.cos(math.radians(20)) + 1e-4, abs=1e-7)
    assert np.all(pos[2:] == 0) and np.all(col[2:] == 0) and np.all(cos_inner[2:] == 1.0)


def test_flicker_partials_are_jittered_each_on_its_own():
    """The partials sit near ln f + (−0.6, −0.5, …, 0.6), each moved by its own seeded jitter within ±0.03
    (irregular beats, not a comb): the one nearest the peak stays within exp(±0.03) of f, and the spacings
    in ln f vary (one shared shift would leave them all 0.1; independent uniform jitter gives them a
    standard deviation of 0.024 ± 0.005 over 12 spacings: bound 0.005)."""
    from igserver.render.point_lights import _partials

    for seed in range(5):
        freqs, _, _ = _partials(F, seed)
        x = np.log(np.sort(freqs) / F)
        assert abs(x[6]) <= 0.03 + 1e-12
        assert np.all(np.abs(x - np.linspace(-0.6, 0.6, 13)) <= 0.03 + 1e-12)
        assert np.std(np.diff(x)) > 0.005, seed
