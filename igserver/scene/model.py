"""The scene model: one typed description of everything the IG draws.

The same model is the protocol's message schema, the scene-file format and the renderer's input.
Every field has a unit, a default and a valid range; NaN, Inf, unknown fields and out-of-range
values are rejected with a message naming the field (pydantic's error ``loc``).

Conventions (docs/design.md#conventions): world frame is local ENU at the scene origin (x east, y north, z up,
metres, float64); angles on the wire are degrees (heading clockwise from north, pitch nose-up,
roll right-wing-down); ``time.utc`` drives sun/moon/stars, ``time.sim_time`` drives animation.
"""

from __future__ import annotations

from datetime import datetime, timezone
from typing import Annotated, Literal, get_args

from pydantic import AfterValidator, BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator
from pydantic_core import InitErrorDetails, PydanticCustomError

from ..assets import ASSET_NAME_PATTERN, AssetError, resolve_asset
from ..assets.gltf import check_model
from ..assets.images import ImageError, check_profile_image
from ..effect_kinds import EFFECT_TYPES, FUEL_NAMES
from .channels import MAX_CHANNELS, Channel, check_clips

# Upper bound on any world coordinate (m). 1e7 m is beyond a continent; float64 keeps mm there.
WORLD_LIMIT_M = 1.0e7

MAX_EFFECTS = 64
MAX_LIGHTS = 256
MAX_ENTITIES = 256
ID_PATTERN = r"^[A-Za-z0-9_.:-]{1,64}$"


class Strict(BaseModel):
    """Base: forbid unknown fields and non-finite floats, re-validate on assignment."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, validate_assignment=True)


Coordinate = Annotated[float, Field(ge=-WORLD_LIMIT_M, le=WORLD_LIMIT_M)]
Vec3 = tuple[Coordinate, Coordinate, Coordinate]
UnitColor = tuple[
    Annotated[float, Field(ge=0.0, le=1.0)],
    Annotated[float, Field(ge=0.0, le=1.0)],
    Annotated[float, Field(ge=0.0, le=1.0)],
]
EntityId = Annotated[str, Field(pattern=ID_PATTERN)]


class Frustum(Strict):
    """Asymmetric frustum as signed half-angles from the view axis (degrees), for multi-channel displays."""

    left: float = Field(-30.0, ge=-89.0, le=89.0, description="deg, negative = left of axis")
    right: float = Field(30.0, ge=-89.0, le=89.0, description="deg")
    bottom: float = Field(-20.0, ge=-89.0, le=89.0, description="deg, negative = below axis")
    top: float = Field(20.0, ge=-89.0, le=89.0, description="deg")

    @model_validator(mode="after")
    def _ordered(self) -> "Frustum":
        if not self.right > self.left:
            raise ValueError("frustum.right must be greater than frustum.left")
        if not self.top > self.bottom:
            raise ValueError("frustum.top must be greater than frustum.bottom")
        return self


class Camera(Strict):
    position: Vec3 = Field((0.0, 0.0, 10.0), description="m, ENU world position (float64)")
    heading: float = Field(0.0, ge=-360.0, le=360.0, description="deg clockwise from north")
    pitch: float = Field(0.0, ge=-90.0, le=90.0, description="deg, nose up positive")
    roll: float = Field(0.0, ge=-180.0, le=180.0, description="deg, right wing down positive")
    fov_y: float = Field(60.0, gt=0.1, lt=170.0, description="deg, vertical field of view (symmetric frustum)")
    frustum: Frustum | None = Field(None, description="asymmetric frustum; overrides fov_y when set")
    near: float = Field(0.1, ge=1e-3, le=1e4, description="m, near clip distance (depth precision does not depend on it)")
    far: float = Field(
        1_000_000.0, ge=1.0, le=1e7,
        description="m, draw distance of entities, lights and effects; the sky and the earth's surface are "
        "drawn to the horizon whatever it is (reversed-Z depth, no far clip plane)",
    )
    width: int = Field(640, ge=16, le=7680, description="px")
    height: int = Field(360, ge=16, le=4320, description="px")
    exposure_ev: float | None = Field(
        None, ge=-20.0, le=20.0, description="EV100 exposure (absolute); None = automatic (an adapting eye)"
    )
    # --- atmosphere engineer: exposure like an eye (render/post/exposure.py) ---
    adaptation: bool = Field(
        True, description="automatic exposure adapts over sim_time (0.4 s to light, 4 s to dark); false = steady state"
    )
    mesopic_vision: bool = Field(
        False, description="render night as the eye sees it: colour fades and shifts blue below ~3 cd/m^2 (Purkinje)"
    )

    @model_validator(mode="after")
    def _clip_order(self) -> "Camera":
        if not self.far > self.near:
            raise ValueError("camera.far must be greater than camera.near")
        return self


class SunOverride(Strict):
    """Instructor override of the sun's position (replaces the ephemeris)."""

    elevation: float = Field(..., ge=-90.0, le=90.0, description="deg above the horizon")
    azimuth: float = Field(..., ge=-360.0, le=360.0, description="deg clockwise from north")


def _default_utc() -> datetime:
    return datetime(2026, 6, 21, 12, 0, tzinfo=timezone.utc)


class Time(Strict):
    utc: datetime = Field(default_factory=_default_utc, description="ISO 8601; drives sun, moon, stars")
    sim_time: float = Field(0.0, ge=0.0, le=1e12, description="s, drives animation (float64)")
    sun_override: SunOverride | None = Field(None, description="fix sun elevation/azimuth instead of the ephemeris")

    @field_validator("utc")
    @classmethod
    def _aware(cls, value: datetime) -> datetime:
        if value.tzinfo is None:
            value = value.replace(tzinfo=timezone.utc)
        # check the year after conversion: 1800-01-01T00:00+23:59 is 1799 in UTC
        try:
            value = value.astimezone(timezone.utc)
        except OverflowError:
            raise ValueError("utc year must be within 1800..2200") from None
        if not (1800 <= value.year <= 2200):
            raise ValueError("utc year must be within 1800..2200")
        return value


class Location(Strict):
    lat: float = Field(59.93, ge=-90.0, le=90.0, description="deg, geodetic latitude of the origin")
    lon: float = Field(30.31, ge=-180.0, le=180.0, description="deg, longitude of the origin")
    altitude: float = Field(0.0, ge=-500.0, le=9000.0, description="m above sea level of the origin")


class Atmosphere(Strict):
    model: Literal["gradient", "precomputed"] = Field(
        "precomputed", description="sky tier: the paper's gradient model or precomputed scattering"
    )
    visibility: float = Field(30_000.0, ge=50.0, le=200_000.0, description="m, meteorological visibility")
    turbidity: float = Field(
        2.0, ge=1.0, le=10.0, description="Linke-style turbidity of the surface layer (tables per class of 0.5)"
    )
    # --- atmosphere engineer: the fog/haze layer (render/sky/haze.py) ---
    fog_top: float | None = Field(
        None, ge=1.0, le=5_000.0,
        description="m above the ground, top of a fog layer of the given visibility; None = haze thinning with height",
    )
    visibility_transition: float = Field(
        1.0, ge=0.0, le=10.0, description="s, a visibility change eases in over this much sim_time (0 = at once)"
    )
    ozone: bool = Field(True, description="include ozone absorption")
    scattering_orders: int = Field(4, ge=1, le=32, description="multiple-scattering orders of the tables")
    quality: Literal["low", "medium", "high"] = Field(
        "medium", description="precomputed table sizes (see igserver quality sky for the error curve)"
    )


class Precipitation(Strict):
    """Rain or snow (docs/design.md#precipitation; drawn by render/precip, physics in igserver/weather.py)."""

    type: Literal["none", "rain", "snow"] = Field("none", description="what falls; none = no particle pass")
    rate: float = Field(
        0.0, ge=0.0, le=200.0, description="mm/h, liquid-water-equivalent rate (snow too); 0 = nothing falls"
    )
    lowers_visibility: bool = Field(
        True,
        description="add the rain/snow extinction to atmosphere.visibility (then the visibility of the air "
        "alone); false = the host's visibility already includes the precipitation",
    )
    streak_time: float = Field(
        1.0 / 60.0, ge=1e-3, le=0.1,
        description="s, exposure of a streak: each particle is drawn from its position this long ago to now "
        "(independent of frame rate and camera motion)",
    )


class Weather(Strict):
    wind_speed: float = Field(5.0, ge=0.0, le=80.0, description="m/s at 10 m")
    wind_direction: float = Field(270.0, ge=0.0, le=360.0, description="deg, direction the wind blows FROM")
    precipitation: Precipitation = Field(default_factory=Precipitation)
    cirrus_coverage: float = Field(0.0, ge=0.0, le=1.0, description="fraction of the sky")
    cirrus_altitude: float = Field(9_000.0, ge=5_000.0, le=14_000.0, description="m above sea level, cirrus layer")
    cirrus_wind_speed: float | None = Field(
        None, ge=0.0, le=120.0, description="m/s, wind at the cirrus layer; None = 4x the surface wind (jet level)"
    )


class Bathymetry(Strict):
    """Sea floor under the water (docs/design.md#water): depth shortens, refracts, shoals and breaks waves."""

    type: Literal["uniform", "slope", "map"] = Field(
        "uniform", description="uniform depth; a plane beach (slope); a height-map image asset (map)")
    depth: float = Field(1000.0, ge=0.001, le=11_000.0,
                         description="m, depth (offshore depth for slope; depth around the map for map)")
    shore_distance: float = Field(500.0, ge=0.0, le=1e6, description="m, origin-to-shoreline distance (slope)")
    shore_heading: float = Field(0.0, ge=0.0, le=360.0, description="deg, direction from origin to shore")
    slope: float = Field(0.02, gt=0.0, le=1.0, description="bottom slope dz/dx (slope)")
    berm_height: float = Field(2.0, ge=0.0, le=20.0,
                               description="m above the still water level, the beach's crest: the foreshore rises at "
                                           "the bottom's slope up to it (slope)")
    dune_height: float = Field(8.0, ge=0.0, le=50.0,
                               description="m, the foredune ridge behind the backshore (0: flat land) (slope)")
    map: str | None = Field(None, max_length=64, pattern=ASSET_NAME_PATTERN, validate_default=True,
                            description="bathymetry asset name: a grey PNG (map)")
    map_center: tuple[Coordinate, Coordinate] = Field((0.0, 0.0), description="m, ENU (x, y) of the image centre (map)")
    map_size: tuple[
        Annotated[float, Field(ge=1.0, le=1e6)], Annotated[float, Field(ge=1.0, le=1e6)]
    ] = Field((2000.0, 2000.0), description="m, ground size of the image across x (width) and y (height) (map)")
    map_heading: float = Field(0.0, ge=0.0, le=360.0, description="deg, compass direction of the image's top (map)")
    map_elevation: tuple[
        Annotated[float, Field(ge=-11_000.0, le=9000.0)], Annotated[float, Field(ge=-11_000.0, le=9000.0)]
    ] = Field((-50.0, 10.0), description="m, bottom elevation above the water level of black and of white (map)")

    @field_validator("map")
    @classmethod
    def _map(cls, value: str | None, info) -> str | None:
        # a field validator, so that its errors point at the map (#/ocean/bathymetry/map); ``type`` is
        # declared first, so it is in info.data when valid
        if value is None:
            if info.data.get("type") == "map":
                raise ValueError("bathymetry.type 'map' needs bathymetry.map (an asset name)")
            return value
        # the asset must exist: checked here, at the protocol edge, not at render time
        try:
            resolve_asset("bathymetry", value, (".png",))
        except AssetError as exc:
            raise ValueError(str(exc)) from None
        return value

    @model_validator(mode="after")
    def _map_elevation(self) -> "Bathymetry":
        if not self.map_elevation[1] > self.map_elevation[0]:
            raise ValueError("bathymetry.map_elevation must be (lower, higher)")
        return self


class Swell(Strict):
    """Long waves from a distant storm, travelling in their own direction (0 m = none)."""

    height: float = Field(0.0, ge=0.0, le=20.0, description="m, significant height of the swell")
    period: float = Field(10.0, ge=4.0, le=25.0, description="s, peak period")
    direction: float = Field(270.0, ge=0.0, le=360.0, description="deg, direction the swell comes FROM")


class Ocean(Strict):
    enabled: bool = False
    sea_state: int | None = Field(None, ge=0, le=9, description="WMO sea state; None = derived from wind")
    fetch_km: float | None = Field(
        None, ge=0.1, le=10_000.0, description="km, distance the wind has blown over open water (0.1 to 10000): "
        "the wind sea grows by the JONSWAP fetch law, capped at the Pierson-Moskowitz fully developed sea; "
        "None = not limiting (both None: the WMO/Beaufort probable height of the wind); a sea_state overrides it")
    duration_h: float | None = Field(
        None, ge=0.1, le=1000.0, description="h, how long the wind has blown (0.1 to 1000): the JONSWAP "
        "duration law; None = not limiting (with fetch_km also None: the WMO/Beaufort probable height); a "
        "sea_state overrides it")
    level: float = Field(0.0, ge=-500.0, le=9000.0, description="m, mean water level (ENU z)")
    bathymetry: Bathymetry = Field(default_factory=Bathymetry)
    swell: Swell = Field(default_factory=Swell)
    steepness: float = Field(
        0.6, ge=0.0, le=1.0, description="Gerstner steepness Q in deep water (0 round, 1 sharpest without loops)")
    wave_count: int = Field(24, ge=4, le=64, description="Gerstner waves displaced by the mesh (and the queries)")
    lod_error: float = Field(1.0, ge=0.25, le=16.0, description="px, screen-space error bound of the sea mesh LOD")
    detail_resolution: int = Field(128, ge=32, le=512, description="texels per side of each detail normal map (the nearest power of two is used)")


class Effect(Strict):
    """A volumetric effect in its bounding container (docs/design.md#fire-and-smoke)."""

    id: EntityId
    type: Literal[EFFECT_TYPES] = "fire"  # igserver/effect_kinds.py
    position: Vec3 = Field((0.0, 0.0, 0.0), description="m, ENU position of the container's base centre")
    diameter: float = Field(2.0, ge=0.0, le=500.0, description="m, base diameter of the fire / plume")
    height: float | None = Field(None, ge=0.0, le=2000.0, description="m, container height; None = Heskestad")
    intensity: float = Field(1.0, ge=0.0, le=10.0, description="relative heat release (1 = nominal)")
    fuel: Literal[FUEL_NAMES] = Field("oil", description="what a fire burns (igserver/effect_kinds.py FUELS): its "
                                      "heat release per pool area, the flame's soot, the smoke's soot and colour")
    heat_release_kw: float | None = Field(
        None, ge=0.0, le=1e7, description="kW, a fire's nominal heat release; None = the pool's area x the fuel's "
        "burning rate x heat of combustion (x intensity either way)")
    active: bool = Field(True, description="burning (fades in) or extinguished (fades out)")
    fade: float = Field(3.0, ge=0.0, le=600.0, description="s, fade-in/out duration")
    emits_smoke: bool = Field(False, description="fire also emits a smoke plume")
    seed: int = Field(1, ge=0, le=2**31 - 1, description="random seed of noise and flicker")
    profile: str | None = Field(
        None, pattern=ASSET_NAME_PATTERN, description="optional profile: the name of a `profiles` asset (PNG; "
        "a name, never a path: see docs/operations.md, Assets)"
    )
    changed_at: float | None = Field(
        None, ge=0.0, le=1e12, description="s, sim_time of the last activate/deactivate (set by the IG)"
    )


    @field_validator("profile")
    @classmethod
    def _profile_asset(cls, value: str | None) -> str | None:
        # the host names an asset; the server's asset directory decides which file (docs/design.md#service)
        if value is not None:
            try:
                # its size from the header: one too big for memory is refused here, not at render time
                check_profile_image(value, resolve_asset("profiles", value, (".png",)))
            except (AssetError, ImageError) as exc:
                raise ValueError(str(exc)) from None
        return value


class Flicker(Strict):
    enabled: bool = False
    frequency: float = Field(1.5, gt=0.0, le=50.0, description="Hz, peak frequency of the variation")
    amplitude: float = Field(0.3, ge=0.0, le=1.0, description="relative intensity variation")
    seed: int = Field(1, ge=0, le=2**31 - 1)


class Light(Strict):
    id: EntityId
    type: Literal["point", "spot"] = "point"
    position: Vec3 = (0.0, 0.0, 5.0)
    color: UnitColor = Field((1.0, 0.85, 0.6), description="linear RGB, 0..1")
    intensity: float = Field(1000.0, ge=0.0, le=1e8, description="cd, luminous intensity")
    range: float = Field(100.0, gt=0.0, le=1e5, description="m, distance where the light is cut off")
    heading: float = Field(0.0, ge=-360.0, le=360.0, description="deg, spot direction")
    pitch: float = Field(0.0, ge=-90.0, le=90.0, description="deg, spot direction")
    cone_inner: float = Field(10.0, ge=0.0, le=90.0, description="deg, spot full-intensity half-angle")
    cone_outer: float = Field(20.0, ge=0.0, le=90.0, description="deg, spot cut-off half-angle")
    flicker: Flicker = Field(default_factory=Flicker)

    @model_validator(mode="after")
    def _cone(self) -> "Light":
        if self.cone_outer < self.cone_inner:
            raise ValueError("cone_outer must be >= cone_inner")
        return self


# --- Surfaces: entities (glTF models), their articulated parts, shadows (docs/surfaces.md) ----------

MAX_PARTS = 32
PART_NAME_PATTERN = r"^[A-Za-z0-9_.:-][A-Za-z0-9_.: -]{0,63}$"
PartName = Annotated[str, Field(pattern=PART_NAME_PATTERN)]


class PartPose(Strict):
    """Pose of an articulated part (a glTF node, by name) relative to its rest pose in the file:
    rotated about the node's own origin (its pivot), then moved; angles in the entity's frame
    conventions (heading about the part's up axis, clockwise seen from above)."""

    heading: float = Field(0.0, ge=-360.0, le=360.0, description="deg, turn about the part's up axis (a radar)")
    pitch: float = Field(0.0, ge=-180.0, le=180.0, description="deg, about the part's starboard axis (a hatch)")
    roll: float = Field(0.0, ge=-180.0, le=180.0, description="deg, about the part's forward axis (a door)")
    offset: tuple[
        Annotated[float, Field(ge=-1e3, le=1e3)],
        Annotated[float, Field(ge=-1e3, le=1e3)],
        Annotated[float, Field(ge=-1e3, le=1e3)],
    ] = Field((0.0, 0.0, 0.0), description="m, translation along the entity's x (starboard), y (forward), z (up)")


class Entity(Strict):
    id: EntityId
    model: str = Field(
        "box", pattern=ASSET_NAME_PATTERN,
        description="model asset name: `box` (built-in 1 m cube, base at z = 0) or a glTF 2.0 model "
                    "(`NAME` or `NAME.glb`/`NAME.gltf`) in the models directory (IGSERVER_ASSETS/models, then "
                    "the packaged models: patrol_boat, pier, buoy, crate, barrel); checked when sent")
    visible: bool = Field(True, description="draw the entity (hidden entities keep their state)")
    position: Vec3 = (0.0, 0.0, 0.0)
    heading: float = Field(0.0, ge=-360.0, le=360.0)
    pitch: float = Field(0.0, ge=-90.0, le=90.0)
    roll: float = Field(0.0, ge=-180.0, le=180.0)
    scale: tuple[
        Annotated[float, Field(gt=0.0, le=1e4)],
        Annotated[float, Field(gt=0.0, le=1e4)],
        Annotated[float, Field(gt=0.0, le=1e4)],
    ] = Field((1.0, 1.0, 1.0), description="factors along the model's x (starboard), y (forward), z (up); "
                                           "models are in metres, so the box's scale is its size in m")
    parts: dict[PartName, PartPose] = Field(
        default_factory=dict, max_length=MAX_PARTS,
        description="articulated parts by glTF node name, e.g. {radar = {heading = 30}}")
    color: UnitColor = Field((0.5, 0.5, 0.5), description="linear base colour (built-in box only)")
    metallic: float = Field(0.0, ge=0.0, le=1.0, description="built-in box only")
    roughness: float = Field(0.6, ge=0.02, le=1.0, description="built-in box only")

    @field_validator("model")
    @classmethod
    def _model_file(cls, v: str) -> str:
        check_model(v)  # pure Python: header check, cached by file identity
        return v

    @model_validator(mode="after")
    def _part_names(self) -> "Entity":
        if self.parts:
            known = check_model(self.model).node_names
            unknown = sorted(set(self.parts) - known)
            if unknown:
                raise ValueError(f"model {self.model!r} has no part (glTF node) named {unknown[0]!r}"
                                 f" (parts: {', '.join(sorted(known)[:20]) or 'none'})")
        return self


class Shadows(Strict):
    """Shadow maps and the paper's shadow terms (docs/design.md#surfaces): in shadow the diffuse light is scaled
    by (1 - d + d * colour) and the specular light is removed."""

    enabled: bool = Field(True, description="sun/moon and spot-light shadow maps (skipped when nothing casts)")
    density: float = Field(1.0, ge=0.0, le=1.0, description="d_sh: 1 = a shadow removes the light, 0 = no shadow")
    color: UnitColor = Field((0.0, 0.0, 0.0), description="c_sh: linear colour a full shadow leaves of the diffuse light")
    softness: float = Field(0.1, ge=0.0, le=5.0, description="m, radius of the soft shadow edge (PCF filter on the receiver)")
    resolution: Literal[512, 1024, 2048, 4096] = Field(1024, description="px, side of the sun/moon shadow map")
    distance: float = Field(400.0, ge=10.0, le=5000.0, description="m, casters farther from the camera cast no shadow")


class Ground(Strict):
    enabled: bool = Field(True, description="draw the flat ground plane at z = level")
    level: float = Field(-0.5, ge=-11_000.0, le=9000.0, description="m, ENU height of the plane")
    color: UnitColor = Field((0.25, 0.24, 0.2), description="linear base colour")
    roughness: float = Field(0.9, ge=0.02, le=1.0)


def _target_fps(v: float) -> float:
    if v != 0.0 and not 5.0 <= v <= 240.0:  # NaN fails both
        raise ValueError("target_fps is 0 (off) or 5-240 frames/s")
    return v


# A frame rate the overload controller holds (render/overload.py): 0 = off, else 5-240 frames/s. Below 5
# a frame is no longer a picture in motion; above 240 no display shows it.
TargetFps = Annotated[float, AfterValidator(_target_fps)]


PresetName = Literal["low", "medium", "high", "auto"]
PRESET_NAMES: tuple[str, ...] = get_args(PresetName)  # the command lines' choices


class Quality(Strict):
    """Quality presets (igserver/render/presets.py): every pipeline's knobs per level, chosen from the
    error-vs-time curves of ``igserver quality``."""

    preset: PresetName = Field(
        "medium", description="knob set of every pipeline; auto = the overload controller chooses the knobs and the "
        "render scale per frame (render/overload.py) to hold target_fps (or, when that is 0, target_ms)")
    target_ms: float = Field(
        40.0, ge=1.0, le=10_000.0, description="ms, frame-time target (render + readback) of the auto preset")
    target_fps: TargetFps = Field(
        0.0, description="frames/s the IG holds by trading detail for time (render scale 1.0-0.5 and, with the "
        "auto preset, every pipeline's knobs; a fixed preset keeps its knobs); 0 = off, else 5-240")


def _unique_ids(items: list, what: str) -> list:
    seen: set[str] = set()
    for item in items:
        if item.id in seen:
            raise ValueError(f"duplicate {what} id {item.id!r}")
        seen.add(item.id)
    return items


class Scene(Strict):
    """The whole state the IG renders. Also the protocol's message body."""

    version: Literal[1] = 1
    host_frame: int = Field(0, ge=0, le=2**63 - 1, description="host frame number this state belongs to")
    camera: Camera = Field(default_factory=Camera)
    time: Time = Field(default_factory=Time)
    location: Location = Field(default_factory=Location)
    atmosphere: Atmosphere = Field(default_factory=Atmosphere)
    weather: Weather = Field(default_factory=Weather)
    ocean: Ocean = Field(default_factory=Ocean)
    ground: Ground = Field(default_factory=Ground)
    effects: list[Effect] = Field(default_factory=list, max_length=MAX_EFFECTS)
    lights: list[Light] = Field(default_factory=list, max_length=MAX_LIGHTS)
    entities: list[Entity] = Field(default_factory=list, max_length=MAX_ENTITIES)
    shadows: Shadows = Field(default_factory=Shadows)
    quality: Quality = Field(default_factory=Quality)
    channels: list[Channel] = Field(
        default_factory=list, max_length=MAX_CHANNELS,
        description="views of the camera's eyepoint rendered together (docs/channels.md); empty = the camera alone")

    @field_validator("effects")
    @classmethod
    def _effect_ids(cls, v):
        return _unique_ids(v, "effect")

    @field_validator("lights")
    @classmethod
    def _light_ids(cls, v):
        return _unique_ids(v, "light")

    @field_validator("entities")
    @classmethod
    def _entity_ids(cls, v):
        return _unique_ids(v, "entity")

    @field_validator("channels")
    @classmethod
    def _channels(cls, v, info):
        # camera is declared before channels: in info.data when it is valid
        return check_clips(_unique_ids(v, "channel"), info.data.get("camera"))

    # -- render budget (svc-runtime): every accepted state renders within a bounded cost (scene/budget.py)
    @model_validator(mode="after")
    def _within_budget(self):
        from .budget import over_budget

        problems = over_budget(self)
        if problems:
            raise ValidationError.from_exception_data("Scene", [
                InitErrorDetails(type=PydanticCustomError("over_budget", message), loc=loc, input=None)
                for loc, message in problems
            ])
        return self

