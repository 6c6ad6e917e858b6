"""Effect state without GL: fade, container size, wind lean, noise time, visibility (docs/design.md#fire-and-smoke).

Everything here is a pure function of the scene, so the FrameGraph's ``needed()`` (no GL state),
the fire lights and the volume pass all agree on which volumes exist and how big they are.

Sizes: a pool fire of diameter D (m) and heat release Q (kW) has a mean flame height
(Heskestad) L = 0.235 Q^0.4 - 1.02 D; Q = intensity x (the host's heat_release_kw, or pi D^2 / 4
x the fuel's q'' = m'' dH_c (1 - exp(-k beta D)), effect_kinds.FUELS; fuel oil: 1.38 MW/m^2 at
D = 3 m). Flame tips reach above L intermittently, so the container is 1.4 L tall.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...effect_kinds import EFFECT_KINDS, FUELS, Fuel
from ...scene.model import Effect, Scene
from ...weather import wind_vector
from ..camera import CameraView

# A fire's plume container: radius over height R / H. The profile's radius grows by 0.7 R over H
# (profiles.py smoke_profile) and its density is half at 0.8 of it, an edge opening at atan(0.8 x
# 0.7 x 0.32) = 10.2 deg; where the smoke thins upward the edge that hides half the sky behind it
# lies further in, and opens at 7.4 deg (measured on the frame: tests/test_volumes.py), inside the
# 6-8 deg half-angle of buoyant plumes' visible edges.
PLUME_SPREAD = 0.32
CONTAINER_OVER_FLAME = 1.4  # container height / mean flame height: room for the intermittent tips
NOISE_PERIOD = 32.0  # lattice units: the noise is periodic along P.z, the scroll is reduced modulo this
NOISE_SCALE = 2.2  # lattice units per container radius (the paper's noiseScale, nominal size)
G = 9.81
MAX_SLABS = 8  # boxes a bent container is drawn as (Volume.slabs)


def fade_level(effect: Effect, sim_time: float) -> float:
    """0 = gone, 1 = fully burning. Smoothstep of the time since the last activate/deactivate.

    ``changed_at`` None means the effect has been in its state forever.
    """
    if effect.changed_at is None:
        return 1.0 if effect.active else 0.0
    if effect.fade <= 0.0:
        s = 1.0 if sim_time >= effect.changed_at else 0.0
    else:
        s = min(max((sim_time - effect.changed_at) / effect.fade, 0.0), 1.0)
    s = s * s * (3.0 - 2.0 * s)
    return s if effect.active else 1.0 - s


def heskestad_height(diameter: float, intensity: float, fuel: str = "oil") -> float:
    """Mean flame height (m) of a pool of ``fuel`` burning at ``intensity`` x its q''."""
    q = max(intensity, 1e-6) * fuel_heat_release_per_area(FUELS[fuel], diameter) * math.pi * diameter**2 / 4.0
    return flame_height(diameter, q)


# Soot of a fire's plume: fuel burnt m_f = Q / dH_c, soot made Y m_f, carried up by the plume at
# its mean speed w through its cross-section pi b^2, so its concentration is c = Y m_f / (w pi b^2)
# and its extinction sigma = sigma_s c, with the fuel's dH_c and soot yield Y (effect_kinds.FUELS)
# and sigma_s = 8.7 m^2/g, the specific extinction of flame-generated soot (Mulholland & Choi
# 1998, 633 nm). The speed is half Heskestad's centreline velocity above the flame, u0 = 3.4
# (g / (c_p T rho))^(1/3) Q_c^(1/3) (z - z0)^(-1/3) = 1.03 Q_c^(1/3) (z - z0)^(-1/3) m/s (Q_c =
# 0.7 Q kW, virtual origin z0 = 0.083 Q^(2/5) - 1.02 D). Further up c falls as (z - z0)^(-5/3)
# (profiles.py smoke_profile).
SOOT_MASS_EXTINCTION = 8.7  # m^2/g


def fuel_heat_release_per_area(fuel: Fuel, diameter: float) -> float:
    """kW/m^2, q'' = m'' dH_c (1 - exp(-k beta D)) of a large pool (Babrauskas 1983)."""
    return fuel.burning_rate * fuel.heat_of_combustion * 1000.0 * (1.0 - math.exp(-fuel.k_beta * diameter))


def effect_heat_release(effect: Effect) -> float:
    """kW, a fire's heat release: the host's heat_release_kw, else its pool's area x the fuel's
    q''; times the intensity either way."""
    nominal = effect.heat_release_kw
    if nominal is None:
        nominal = fuel_heat_release_per_area(FUELS[effect.fuel], effect.diameter) * math.pi * effect.diameter**2 / 4.0
    return max(effect.intensity, 1e-6) * nominal


def flame_height(diameter: float, q_kw: float) -> float:
    """Heskestad's mean flame height (m) of a pool fire of heat release q_kw; at least 0.5 D so
    small fires keep a flame."""
    if diameter <= 0.0:
        return 0.0
    return max(0.235 * max(q_kw, 1e-6) ** 0.4 - 1.02 * diameter, 0.5 * diameter)


def plume_soot_extinction(effect: Effect, base_height: float, base_radius: float) -> float:
    """1/m, extinction of a fire plume's soot where the plume starts, ``base_height`` m above the
    pool with radius ``base_radius`` m (its half-density radius)."""
    fuel = FUELS[effect.fuel]
    diameter = effect.diameter
    q = effect_heat_release(effect)
    z0 = 0.083 * q**0.4 - 1.02 * diameter
    z = max(base_height, flame_height(diameter, q), z0 + 0.5)
    w = 0.5 * 1.03 * (0.7 * q) ** (1.0 / 3.0) * (z - z0) ** (-1.0 / 3.0)
    soot = fuel.soot_yield * q / (fuel.heat_of_combustion * 1000.0) * 1000.0  # g/s
    return SOOT_MASS_EXTINCTION * soot / (w * math.pi * max(base_radius, 0.05) ** 2)


def puffing_frequency(diameter: float) -> float:
    """Pool-fire puffing frequency f = 1.5 / sqrt(D) Hz (D in m), finite for D -> 0."""
    return 1.5 / math.sqrt(max(diameter, 0.01))


@dataclass(frozen=True)
class Volume:
    """One ray-marched container: a fire, a smoke plume, or the smoke of a fire."""

    key: tuple[str, str]  # (effect id, "fire" | "smoke"): the effect's own container or its plume
    kind: str  # the volume's effect kind (igserver/effect_kinds.py): the effect's, or its plume's
    base: np.ndarray  # world ENU of the base centre, float64
    radius: float  # m, container half-width (max radius of the profile), after fade
    height: float  # m, after fade
    nominal_radius: float  # m, before fade: the noise is attached to the nominal size
    lean: np.ndarray  # m, horizontal offset of the top (wind): fire axis tilts straight, a plume bends (z/H)^2
    opacity: float  # profile opacity (fade)
    level: float  # fade level 0..1
    intensity: float
    rise_speed: float  # m/s, upward speed of the turbulence
    seed: int
    profile: str | None
    effect: Effect

    @property
    def box(self) -> tuple[np.ndarray, np.ndarray]:
        """World AABB of the (wind-bent) container."""
        r = self.radius
        lo = self.base + np.array([min(-r, self.lean[0] - r), min(-r, self.lean[1] - r), 0.0])
        hi = self.base + np.array([max(r, self.lean[0] + r), max(r, self.lean[1] + r), self.height])
        return lo, hi

    def slabs(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """World AABBs of equal height slabs of the container, bottom first, tight around the bent
        axis (march.frag.glsl to_volume: offset lean z for a fire, lean z² for a plume, at height
        fraction z) ± the radius. A plume bent over by the wind fills a fraction of its one AABB
        (the demo's: about a fifth), and every pixel of the box's screen area marches; slabs of
        about a radius of lean each leave a staircase around it. At most MAX_SLABS."""
        r = self.radius
        count = int(min(max(math.ceil(float(np.linalg.norm(self.lean)) / max(r, 1e-6)), 1), MAX_SLABS))
        z = np.linspace(0.0, 1.0, count + 1)
        bent = EFFECT_KINDS[self.kind].container == "plume"
        offset = self.lean[None, :] * (z * z if bent else z)[:, None]  # monotonic in z
        boxes = []
        for k in range(count):
            a, b = offset[k], offset[k + 1]
            lo = self.base + np.array([min(a[0], b[0]) - r, min(a[1], b[1]) - r, z[k] * self.height])
            hi = self.base + np.array([max(a[0], b[0]) + r, max(a[1], b[1]) + r, z[k + 1] * self.height])
            boxes.append((lo, hi))
        return boxes

    @property
    def bounding_sphere(self) -> tuple[np.ndarray, float]:
        lo, hi = self.box
        return 0.5 * (lo + hi), 0.5 * float(np.linalg.norm(hi - lo))

    def puff_phase(self, sim_time: float) -> float:
        """rad, 2 pi f t of the pool fire's puffing (f = puffing_frequency(D)), reduced modulo 2 pi
        in float64 (a per-effect start from the seed)."""
        f = puffing_frequency(self.effect.diameter)
        return float(math.fmod(2.0 * math.pi * f * sim_time + (self.seed % 7919) * 2.399963, 2.0 * math.pi))

    @property
    def puff_wavenumber(self) -> float:
        """rad/m, k = 2 pi f / w: the toroidal vortices shed at the puffing frequency f rise at
        the flame's buoyant speed w (rise_speed), so its necks and bulges lie w / f apart. The
        flame's radius at height z (m above the base) is scaled by 1 + a sin(puff_phase - k z)."""
        return 2.0 * math.pi * puffing_frequency(self.effect.diameter) / max(self.rise_speed, 1e-3)

    def noise_offset(self, sim_time: float) -> float:
        """Noise scroll along P.z in lattice units, reduced modulo the period in float64.

        P = (q / lambda) - (0, 0, tau), lambda = nominal radius / noiseScale; tau grows by
        rise_speed / lambda per second. fmod in float64 keeps sim_time = 1e9 s as exact as 100 s,
        and the noise's period along z makes the wrap invisible.
        """
        wavelength = self.nominal_radius / NOISE_SCALE
        phase = (self.seed % 9973) * 0.618034  # per-effect start, lattice units
        return float(math.fmod(sim_time * self.rise_speed / wavelength + phase, NOISE_PERIOD))


def _wind_vector(scene: Scene) -> np.ndarray:
    """m/s, horizontal: the one wind (igserver.weather.wind_vector) that also slants the rain."""
    return wind_vector(scene)[:2]


def effect_volumes(effect: Effect, scene: Scene) -> list[Volume]:
    """The containers of one effect at the scene's sim_time (empty when it is invisible)."""
    level = fade_level(effect, scene.time.sim_time)
    d = effect.diameter
    if level <= 0.0 or d <= 0.0 or effect.intensity <= 0.0:
        return []
    wind = _wind_vector(scene)
    # Paper: activation animates the container size and the profile opacity.
    grow = 0.35 + 0.65 * level
    base = np.asarray(effect.position, dtype=np.float64)
    volumes = []
    kind = EFFECT_KINDS[effect.type]
    if kind.container != "plume":  # a flame
        if kind.container == "jet":
            height = effect.height if effect.height is not None else 2.5 * d * math.sqrt(effect.intensity)
            radius = 0.5 * d
        else:
            height = (effect.height if effect.height is not None
                      else CONTAINER_OVER_FLAME * flame_height(d, effect_heat_release(effect)))
            radius = 0.55 * d  # the base flares a little beyond the pool
        if height <= 0.0:
            return []
        # Flame tilt in a cross wind: tan(theta) ~ u / sqrt(g D) (Froude scaling), at most 45 deg.
        tilt = min(0.45 * float(np.linalg.norm(wind)) / math.sqrt(G * d), 1.0)
        if kind.container == "jet":
            tilt /= 3.0  # a jet's momentum keeps it nearly upright
        lean = wind / max(np.linalg.norm(wind), 1e-9) * tilt * height * grow
        rise = 0.8 * math.sqrt(G * d)  # buoyant velocity scale of the flame, m/s
        volumes.append(Volume((effect.id, "fire"), kind.name, base, radius * grow, height * grow,
                              radius, lean, level, level, effect.intensity, rise, effect.seed,
                              effect.profile, effect))
        if effect.emits_smoke and kind.plume is not None:
            s_base = base + np.array([lean[0] * 0.5, lean[1] * 0.5, 0.55 * height * grow])
            s_height = max(6.0 * d, 2.0 * height) * grow
            s_radius = max(1.4 * d, PLUME_SPREAD * s_height / grow) * grow
            volumes.append(_smoke(effect, kind.plume, s_base, s_radius, s_height, 1.4 * d, level, wind, None))
    else:
        height = effect.height if effect.height is not None else 5.0 * d
        if height <= 0.0:
            return []
        volumes.append(_smoke(effect, kind.name, base, 1.25 * d * grow, height * grow, 1.25 * d, level, wind,
                              effect.profile))
    return volumes


def _smoke(effect, kind, base, radius, height, nominal_radius, level, wind, profile) -> Volume:
    # A plume rises at a few m/s and drifts with the wind: the top moves by height * u / w_rise.
    rise = 3.0
    drift = min(float(np.linalg.norm(wind)) / rise, 1.5)
    lean = wind / max(np.linalg.norm(wind), 1e-9) * drift * height
    return Volume((effect.id, "smoke"), kind, base, radius, height, nominal_radius, lean, level, level,
                  effect.intensity, rise, effect.seed ^ 0x5BD1E995, profile, effect)


def scene_volumes(scene: Scene) -> list[Volume]:
    return [v for e in scene.effects for v in effect_volumes(e, scene)]


def visible_volumes(scene: Scene, view: CameraView) -> list[Volume]:
    """Volumes that exist and intersect the view frustum, far to near (for blending)."""
    out = []
    for vol in scene_volumes(scene):
        centre, radius = vol.bounding_sphere
        if view.sphere_visible(centre, radius):
            out.append(vol)
    out.sort(key=lambda v: -float(np.linalg.norm(view.relative(v.bounding_sphere[0]))))
    return out
