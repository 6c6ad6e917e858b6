"""Effect and light physics without GL: flame height, container, wind lean, draw order, host lights,
light selection, fire-light placement. Written to pin what mutation testing showed the suite left free
(scripts/mutation.sh); each expected value is computed here from the published formula or geometry."""

from __future__ import annotations

import math

import numpy as np
import pytest

from igserver.render.camera import make_view
from igserver.photometry import LUMA
from igserver.render.lights import gather_lights, host_lights
from igserver.render.volumes.effects import effect_volumes, heskestad_height, visible_volumes
from igserver.render.volumes.fire_lights import fire_light
from igserver.scene import Scene

G = 9.81  # m/s^2


def heskestad_reference(diameter: float, intensity: float) -> float:
    """Heskestad's mean flame height L = 0.235 Q^(2/5) - 1.02 D (m, Q in kW) of a pool of the default
    fuel, fuel oil, releasing q'' = m'' dH_c (1 - exp(-k beta D)) = 0.035 kg/m^2 s x 39.7 MJ/kg x
    (1 - exp(-1.7 /m D)) (Babrauskas 1983) times the effect's intensity, at least half a diameter."""
    q = intensity * 0.035 * 39.7e3 * (1.0 - math.exp(-1.7 * diameter)) * math.pi * diameter**2 / 4.0
    return max(0.235 * q**0.4 - 1.02 * diameter, 0.5 * diameter)


@pytest.mark.parametrize("diameter, intensity", [(0.5, 1.0), (2.0, 1.0), (3.0, 0.5), (10.0, 2.0), (5.0, 1e-3)])
def test_flame_height_is_heskestads(diameter, intensity):
    assert heskestad_height(diameter, intensity) == pytest.approx(heskestad_reference(diameter, intensity), rel=1e-9)


def test_flame_height_edges():
    assert heskestad_height(0.0, 1.0) == 0.0  # no pool, no flame
    assert heskestad_height(5.0, 1e-3) == pytest.approx(2.5)  # a smouldering pool keeps half a diameter
    assert heskestad_height(2.0, 0.0) == pytest.approx(heskestad_reference(2.0, 1e-6))  # finite at zero


def _scene(effects, wind_speed=0.0, wind_direction=0.0, camera=None) -> Scene:
    return Scene.model_validate({"camera": camera or {"position": [0.0, -20.0, 2.0]}, "time": {"sim_time": 100.0},
                                 "weather": {"wind_speed": wind_speed, "wind_direction": wind_direction},
                                 "effects": effects})


def test_fire_container_at_full_fade():
    scene = _scene([{"id": "f", "diameter": 2.0}])
    (fire,) = effect_volumes(scene.effects[0], scene)
    assert fire.height == pytest.approx(1.4 * heskestad_reference(2.0, 1.0))  # room for intermittent tips
    assert fire.radius == pytest.approx(0.55 * 2.0)  # the base flares a little beyond the pool
    assert fire.opacity == 1.0 and np.allclose(fire.lean, 0.0)


@pytest.mark.parametrize("direction, downwind", [(270.0, (1.0, 0.0)), (0.0, (0.0, -1.0)), (90.0, (-1.0, 0.0))])
def test_wind_leans_the_fire_downwind_by_the_froude_tilt(direction, downwind):
    """Wind *from* 270 deg (west) blows to the east: the flame tips east by tan(theta) = 0.45 u / sqrt(g D)."""
    u, d = 3.0, 2.0
    scene = _scene([{"id": "f", "diameter": d}], wind_speed=u, wind_direction=direction)
    (fire,) = effect_volumes(scene.effects[0], scene)
    tilt = 0.45 * u / math.sqrt(G * d)
    assert fire.lean == pytest.approx(np.array(downwind) * tilt * fire.height, abs=1e-9)


def test_volumes_are_drawn_far_to_near():
    effects = [{"id": "near", "position": [0.0, 0.0, 0.0]}, {"id": "far", "position": [0.0, 60.0, 0.0]},
               {"id": "mid", "position": [0.0, 30.0, 0.0]}]
    scene = _scene(effects)
    order = [v.key[0] for v in visible_volumes(scene, make_view(scene.camera))]
    assert order == ["far", "mid", "near"]  # back to front, as blending needs


def test_host_lights_colour_intensity_and_spot_axis():
    scene = Scene.model_validate({"lights": [
        {"id": "p", "position": [1.0, 2.0, 3.0], "color": [1.0, 0.5, 0.25], "intensity": 400.0, "range": 50.0},
        {"id": "s", "type": "spot", "heading": 90.0, "pitch": -30.0, "cone_inner": 10.0, "cone_outer": 20.0},
    ]})
    point, spot = host_lights(scene)
    assert point.position.tolist() == [1.0, 2.0, 3.0] and point.range == 50.0
    assert point.color == pytest.approx([400.0, 200.0, 100.0]) and point.spot_dir is None
    # heading 90 (east), pitch -30: the axis points east and down
    assert spot.spot_dir == pytest.approx([math.cos(math.radians(30.0)), 0.0, -0.5], abs=1e-12)
    assert spot.cos_inner == pytest.approx(math.cos(math.radians(10.0)))
    assert spot.cos_outer == pytest.approx(math.cos(math.radians(20.0)))


def test_host_light_flicker_varies_the_intensity_around_its_mean():
    def intensity(t: float) -> float:
        scene = Scene.model_validate({"time": {"sim_time": t}, "lights": [
            {"id": "l", "intensity": 100.0, "color": [1.0, 1.0, 1.0], "flicker": {"enabled": True, "amplitude": 0.3}}]})
        return float(host_lights(scene)[0].color[0])

    values = np.array([intensity(t) for t in np.arange(0.0, 20.0, 0.05)])
    assert values.std() > 5.0 and abs(values.mean() - 100.0) < 5.0


def test_gather_lights_keeps_the_brightest_at_the_camera():
    camera = {"position": [0.0, 0.0, 2.0], "heading": 0.0}
    lights = [  # (intensity, distance ahead): importance = intensity / d^2
        {"id": "a", "position": [0.0, 10.0, 2.0], "intensity": 100.0, "range": 1000.0},   # 1.0
        {"id": "b", "position": [0.0, 100.0, 2.0], "intensity": 50000.0, "range": 1000.0},  # 5.0
        {"id": "c", "position": [0.0, 20.0, 2.0], "intensity": 1200.0, "range": 1000.0},  # 3.0
        {"id": "off", "position": [0.0, 5.0, 2.0], "intensity": 0.0},
        {"id": "behind", "position": [0.0, -500.0, 2.0], "intensity": 1e6, "range": 10.0},
    ]
    scene = Scene.model_validate({"camera": camera, "lights": lights, "ground": {"enabled": False}})
    chosen = gather_lights(scene, make_view(scene.camera), 2)
    assert [l.position[1] for l in chosen] == [100.0, 20.0]
    near = Scene.model_validate({"camera": camera, "lights": [
        {"id": "x", "position": [0.0, 0.5, 2.0], "intensity": 10.0}, {"id": "y", "position": [0.0, 0.9, 2.0], "intensity": 20.0}]})
    # inside 1 m the distance no longer counts (no blow-up): the brighter one first
    assert [l.position[1] for l in gather_lights(near, make_view(near.camera), 2)] == [0.9, 0.5]


def test_fire_light_sits_in_the_flame_and_gas_burners_light_blue():
    scene = _scene([{"id": "f", "diameter": 2.0, "position": [5.0, 6.0, 1.0]},
                    {"id": "g", "type": "gas_burner", "diameter": 1.0}])
    fire = fire_light(scene.effects[0], scene)
    flame = heskestad_reference(2.0, 1.0)
    assert fire.position == pytest.approx([5.0, 6.0, 1.0 + 0.3 * flame])  # glow centroid at 30 % of the flame
    gas = fire_light(scene.effects[1], scene)
    assert gas is not None and gas.color[2] > gas.color[0]
    smoke = _scene([{"id": "s", "type": "smoke"}])
    assert fire_light(smoke.effects[0], smoke) is None


def _luminance(rgb) -> float:
    return float(np.dot(LUMA, rgb))


def test_fire_light_range_is_where_its_illuminance_falls_to_the_threshold():
    """Inverse square law: the range is the distance where I / r^2 = 0.02 lux (fire_lights.MIN_ILLUMINANCE)."""
    scene = _scene([{"id": "f", "diameter": 2.0}])
    light = fire_light(scene.effects[0], scene)
    intensity = _luminance(light.color)  # the colour is normalised to unit luminance
    assert intensity > 0.0 and intensity / light.range**2 == pytest.approx(0.02, rel=1e-9)


def test_fire_light_scales_with_flame_area_and_sqrt_intensity():
    """I ~ sqrt(intensity) x projected flame area (0.55 D wide x Heskestad L tall): quadrupling the
    intensity doubles the first factor and lengthens the flame; same seed and time, same flicker."""
    def intensity(i: float) -> float:
        scene = _scene([{"id": "f", "diameter": 2.0, "intensity": i}])
        return _luminance(fire_light(scene.effects[0], scene).color)

    expected = 2.0 * heskestad_reference(2.0, 4.0) / heskestad_reference(2.0, 1.0)
    assert intensity(4.0) / intensity(1.0) == pytest.approx(expected, rel=1e-9)


def test_a_dying_fire_light_reddens_and_dims():
    def light(active: bool, sim_time: float):
        scene = Scene.model_validate({"time": {"sim_time": sim_time}, "effects": [
            {"id": "f", "diameter": 2.0, "active": active, "changed_at": 100.0, "fade": 4.0}]})
        return fire_light(scene.effects[0], scene)

    burning, dying = light(True, 110.0), light(False, 102.0)  # dying: half-way through its fade-out
    # red over green (a ~1,650 K blackbody's blue is outside the Rec. 709 gamut, clipped to 0): green
    # falls as 0.75^(3 x cooling), cooling 1/2 half-way
    assert dying.color[0] / dying.color[1] == pytest.approx(0.75**-1.5 * burning.color[0] / burning.color[1])
    growing = light(True, 102.0)  # growing at the same level keeps the burning colour
    assert growing.color[0] / growing.color[1] == pytest.approx(burning.color[0] / burning.color[1])


def test_blackbody_photometry_from_planck_and_the_cie_observer():
    """The old candela: a blackbody at the freezing point of platinum (2042 K) has a luminance of
    60 cd/cm^2 (CIPM 1946-1979); the fitted y-bar peaks at 555 nm with 1.0."""
    from igserver.render.volumes.planck import blackbody_xyz, cie_1931

    assert blackbody_xyz(2042.0)[1] == pytest.approx(6.0e5, rel=0.02)
    assert cie_1931(555.0)[1] == pytest.approx(1.0, abs=0.01)


def _planckian_locus_uv(kelvin: float) -> np.ndarray:
    """CIE 1960 (u, v) of the Planckian locus at 1667-2222 K: Kim et al., "Design of advanced colour
    temperature control system for HDTV applications", J. Korean Phys. Soc. 41, 2002 (cubic
    splines of x(T) and y(x), within 0.001 of the integrated locus there)."""
    t = kelvin
    x = -0.2661239e9 / t**3 - 0.2343589e6 / t**2 + 0.8776956e3 / t + 0.179910
    y = -1.1063814 * x**3 - 1.34811020 * x**2 + 2.18555832 * x - 0.20219683
    d = -2.0 * x + 12.0 * y + 3.0
    return np.array([4.0 * x / d, 6.0 * y / d])


@pytest.mark.parametrize("diameter, fuel", [(0.5, "oil"), (1.0, "oil"), (1.0, "wood"), (0.5, "gasoline")])
def test_fire_light_colour_is_the_blackbody_its_radiated_power_implies(diameter, fuel):
    """The fire light's colour is a blackbody's at the flame's emission temperature T: the one whose
    luminous efficacy is the light's lumens over the radiated third of the heat release,
    4 pi I / (Q / 3) (fire_lights.py). Its chromaticity lies on the Planckian locus at T within
    0.01 in (u, v) (measured 0.005-0.006: the CIE fit's 0.002-0.004 and the clipping of the blue
    outside the Rec. 709 gamut), where a fixed 1,350 K of three sampled wavelengths lay 0.06 off."""
    from igserver.render.volumes.effects import effect_heat_release
    from igserver.render.volumes.fire_lights import RADIATIVE_FRACTION, emission_temperature
    from igserver.render.volumes.planck import RGB_TO_XYZ, luminous_efficacy

    scene = _scene([{"id": "f", "diameter": diameter, "fuel": fuel}])
    effect = scene.effects[0]
    kelvin = emission_temperature(effect, scene)
    assert 1667.0 <= kelvin <= 2222.0  # measured 1,702-1,761 K (the locus fit starts at 1,667 K)
    flame = heskestad_height(diameter, 1.0, fuel)
    intensity = 0.3 * 2.0e4 * 0.55 * diameter * flame  # 0.3 x core luminance x 0.5 (1.1 D) L
    efficacy = 4.0 * math.pi * intensity / (RADIATIVE_FRACTION * effect_heat_release(effect) * 1000.0)
    assert luminous_efficacy(kelvin) == pytest.approx(efficacy, rel=0.01)
    X, Y, Z = RGB_TO_XYZ @ fire_light(effect, scene).color
    uv = np.array([4.0 * X, 6.0 * Y]) / (X + 15.0 * Y + 3.0 * Z)
    assert np.linalg.norm(uv - _planckian_locus_uv(kelvin)) < 0.01, (kelvin, uv, np.linalg.norm(uv - _planckian_locus_uv(kelvin)))


def test_flame_height_follows_the_heat_release_and_the_fuel():
    # Heskestad: L = 0.235 Q^(2/5) - 1.02 D (Q in kW); the container is 1.4 L tall. The host's
    # heat_release_kw sets Q (times the intensity); without it the pool's area times the fuel's
    # q'' = m'' dH_c (1 - exp(-k beta D)) (Babrauskas 1983): gasoline, D = 3 m:
    # 0.055 kg/m^2 s x 43.7 MJ/kg x (1 - e^-6.3) = 2,388 kW/m^2, Q = 16.9 MW, L = 7.9 m.
    # Exact up to float rounding.
    import math
    from igserver.render.volumes.effects import CONTAINER_OVER_FLAME, effect_heat_release
    from igserver.scene.model import Effect, Scene
    scene = Scene.model_validate({"weather": {"wind_speed": 0.0}})
    for fields, q in (({"heat_release_kw": 20000.0}, 20000.0),
                      ({"heat_release_kw": 20000.0, "intensity": 0.5}, 10000.0),
                      ({"fuel": "gasoline"}, 0.055 * 43.7e3 * (1.0 - math.exp(-2.1 * 3.0)) * math.pi * 9.0 / 4.0)):
        effect = Effect.model_validate({"id": "f", "diameter": 3.0, **fields})
        assert effect_heat_release(effect) == pytest.approx(q, rel=1e-9)
        flame = next(v for v in effect_volumes(effect, scene) if v.key[1] == "fire")
        assert flame.height == pytest.approx(CONTAINER_OVER_FLAME * (0.235 * q**0.4 - 1.02 * 3.0), rel=1e-9)


def test_plume_soot_by_fuel():
    # The plume's extinction is its soot: yield x fuel burnt / (speed x area) x 8.7 m^2/g, so at the
    # same heat release it scales as yield / dH_c: oil 0.06 / 39.7 against wood 0.015 / 17.0 (1.7x
    # less soot a kW) and methanol, which makes none (a clean blue flame, no smoke).
    from igserver.render.volumes.effects import plume_soot_extinction
    from igserver.scene.model import Effect

    def sigma(fuel):
        return plume_soot_extinction(Effect.model_validate({"id": "f", "diameter": 3.0, "fuel": fuel,
                                                            "heat_release_kw": 10000.0}), 5.0, 1.0)
    assert sigma("oil") / sigma("wood") == pytest.approx((0.06 / 39.7) / (0.015 / 17.0), rel=1e-9)
    assert sigma("methanol") == 0.0
    assert 2.0 < sigma("oil") < 20.0  # 1/m: a dense black plume (its optical depth across ~ sigma 2 m)


@pytest.mark.parametrize("kelvin, published", [(1000.0, (255, 56, 0)), (1500.0, (255, 109, 0)),
                                               (1800.0, (255, 126, 0)), (2000.0, (255, 137, 18)),
                                               (2500.0, (255, 161, 72))])
def test_flame_colour_by_temperature_is_the_blackbodys(kelvin, published):
    """The flame profile's colour at T is Planck's law integrated against the CIE observer: sRGB of a
    blackbody scaled to its brightest channel, against Charity's published table ("What color is a
    blackbody?", vendian.org, 2001: CIE 1964 10-deg observer, D65 white point). Bound 10 levels of
    green and blue: the 2-deg (1931) observer here against the table's 10-deg one, and the
    Wyman-Sloan-Shirley fit (measured 2-4 levels, 9 at 1,000 K where the observers differ most). Three sampled wavelengths gave (254, 150, 49) at
    1,500 K: 41 levels too green, the yellow of a 2,800 K lamp."""
    from igserver.render.volumes.profiles import blackbody_rgb

    c = np.clip(blackbody_rgb(kelvin), 0.0, 1.0)
    srgb = np.where(c <= 0.0031308, 12.92 * c, 1.055 * c ** (1 / 2.4) - 0.055) * 255.0
    assert abs(srgb[0] - published[0]) <= 1.0, (kelvin, srgb)
    assert abs(srgb[1] - published[1]) <= 10.0, (kelvin, srgb)
    assert abs(srgb[2] - published[2]) <= 10.0, (kelvin, srgb)
