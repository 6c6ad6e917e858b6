"""The kinds of volumetric effect (``Effect.type``), one entry each: what the scene model accepts, what
the budget counts, how the volumes pass models and shades a kind's container, and whether it casts a
flickering light (docs/design.md#fire-and-smoke). The scene model, the budget, the effect state
(render/volumes/effects.py), the volumes pass and the fire lights all read this table, so a new kind
that reuses the containers, profiles and shading models below is one entry here.

Below both the scene model and the renderer: plain data, no imports from the package.
"""

from __future__ import annotations

from dataclasses import dataclass

CONTAINERS = ("pool_fire", "jet", "plume")  # render/volumes/effects.py sizes each
SHADINGS = ("emissive", "scattering")  # render/volumes/march.frag.glsl (scattering: SMOKE)


@dataclass(frozen=True)
class EffectKind:
    name: str
    # Container model, sized in render/volumes/effects.py:
    #   pool_fire  Heskestad's mean flame height L of a pool of diameter D, container 1.4 L tall, radius
    #              0.55 D, leaning with the wind by the Froude tilt tan(theta) ~ u / sqrt(g D)
    #   jet        a burner's flame 2.5 D sqrt(intensity) tall, radius 0.5 D, a third of that tilt
    #   plume      a smoke plume 5 D tall, radius 1.25 D, bent by the wind as (z / H)^2
    container: str
    profile: str  # procedural profile (render/volumes/profiles.py) when the effect names none
    # emissive: the profile's colour is emitted light (cd/m^2 x the flame luminance); scattering: it is
    # the albedo of a medium lit by the sun, the sky and the glow of its fire
    shading: str
    # how far the turbulence displaces the profile's height lookup, v = z + roughness turb sqrt(z)
    # (render/volumes/model.comp.glsl; z, v in container heights, turb ~ +-1): ragged flames, smooth jets
    roughness: float
    # relative amplitude of the flame light's flicker about 1 at the puffing frequency 1.5 / sqrt(D) Hz;
    # None: the kind casts no light
    flicker: float | None = None
    # the light's colour: None = a blackbody at the flame's emission temperature (fire_lights.py: the
    # luminous efficacy of its light over a third of its heat release), reddening as a dying fire cools;
    # else this linear rgb (scaled to unit luminance)
    light_rgb: tuple[float, float, float] | None = None
    # the kind of the plume ``emits_smoke`` adds (a second volume: sooty, lit by the flame); None: the
    # kind ignores emits_smoke
    plume: str | None = None

    def __post_init__(self):
        assert self.container in CONTAINERS and self.shading in SHADINGS, self
        assert self.plume is None or self.container != "plume", "a plume emits no plume"

    @property
    def casts_light(self) -> bool:
        return self.flicker is not None

    def volume_count(self, emits_smoke: bool) -> int:
        """Ray-marched containers of one effect of this kind: the budget's weight."""
        return 2 if self.plume is not None and emits_smoke else 1


# In the order the scene model's schema lists them.
EFFECT_KINDS: dict[str, EffectKind] = {kind.name: kind for kind in (
    EffectKind("fire", container="pool_fire", profile="fire", shading="emissive", roughness=0.6, flicker=0.35,
               plume="smoke"),
    EffectKind("smoke", container="plume", profile="smoke", shading="scattering", roughness=0.35),
    EffectKind("gas_burner", container="jet", profile="gas_burner", shading="emissive", roughness=0.12,
               flicker=0.06, light_rgb=(0.55, 0.65, 1.0)),
)}
EFFECT_TYPES = tuple(EFFECT_KINDS)


@dataclass(frozen=True)
class Fuel:
    """What burns in a pool fire (``Effect.fuel``): its heat release per pool area and its soot.

    Large-pool burning: q'' = m'' dH_c (1 - exp(-k beta D)) (Babrauskas 1983, "Estimating large
    pool fire burning rates", Fire Technology 19, and the SFPE Handbook's table of m'', dH_c, k beta;
    wood: a stacked fuel bed of pallets or cribs per its floor area). k beta is also the flame's soot
    absorption per metre (render/volumes/march.py: the flame's optical depth k D). Soot yields
    (g of soot per g burnt) after Tewarson (SFPE Handbook): the smoke's extinction follows them
    (render/volumes/effects.py plume_soot_extinction); its albedo: black soot to grey wood smoke."""

    name: str
    burning_rate: float  # kg/m^2 s, m'' of a large pool
    heat_of_combustion: float  # MJ/kg
    k_beta: float  # 1/m
    soot_yield: float  # g/g
    smoke_albedo: float  # single-scattering albedo of its smoke


FUELS: dict[str, Fuel] = {fuel.name: fuel for fuel in (
    Fuel("oil", burning_rate=0.035, heat_of_combustion=39.7, k_beta=1.7, soot_yield=0.06, smoke_albedo=0.25),
    Fuel("gasoline", burning_rate=0.055, heat_of_combustion=43.7, k_beta=2.1, soot_yield=0.04, smoke_albedo=0.25),
    Fuel("kerosene", burning_rate=0.039, heat_of_combustion=43.2, k_beta=3.5, soot_yield=0.042, smoke_albedo=0.25),
    Fuel("crude", burning_rate=0.035, heat_of_combustion=42.6, k_beta=2.8, soot_yield=0.08, smoke_albedo=0.2),
    Fuel("wood", burning_rate=0.07, heat_of_combustion=17.0, k_beta=1.0, soot_yield=0.015, smoke_albedo=0.85),
    Fuel("methanol", burning_rate=0.017, heat_of_combustion=20.0, k_beta=0.1, soot_yield=0.0, smoke_albedo=0.9),
)}
FUEL_NAMES = tuple(FUELS)

