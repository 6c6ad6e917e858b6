"""Per-frame data every pass reads: the scene, the camera view, light, exposure, targets."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property, lru_cache

import moderngl
import numpy as np

from ..astro import celestial_state, direction_enu
from ..photometry import LUMA
from ..scene.model import Scene
from .camera import CameraView, gl_matrix, make_view
from .depth import zero_to_one
from .frame_block import MAX_LIGHTS, FrameBlock
from .light_tiles import LightTiles
from .lights import FrameLights, PointLight, gather_lights, light_uniforms
from .memo import Memo
from .post.exposure import (GROUND_REFLECTANCE, EyeAdaptation, display_metered_ev100, exposure_of_ev100,
                            frustum_directions)
from .post.meter_lag import MeterLag
from .sky.daylight import SUN_ANGULAR_RADIUS, Daylight
from .sky.frame_sky import SkyFrame, sky_frame
from .sky.haze import HazeTransition

# Point/spot lights per frame (MAX_LIGHTS: the frame block's arrays), the brightest at the camera
# first. Where some lights reach only part of the view, a pixel loops over its screen tile's lights
# only (light_tiles.py).


@dataclass(frozen=True)
class SunMoon:
    sun_elevation: float
    sun_azimuth: float
    moon_elevation: float
    moon_azimuth: float
    moon_phase: float

    @cached_property
    def sun_dir(self) -> np.ndarray:
        return _read_only(np.array(direction_enu(self.sun_elevation, self.sun_azimuth)))

    @cached_property
    def moon_dir(self) -> np.ndarray:
        return _read_only(np.array(direction_enu(self.moon_elevation, self.moon_azimuth)))


def _read_only(a: np.ndarray) -> np.ndarray:
    a.flags.writeable = False
    return a


# The ephemeris per (utc, place): sim_time does not move the sky, so a stream asks for the same
# state every frame.
_celestial_state = lru_cache(maxsize=64)(celestial_state)


def sun_and_moon(scene: Scene) -> SunMoon:
    """From the ephemeris, or the instructor's fixed sun (the moon stays on the ephemeris); one
    object while its inputs stay the same (its directions computed once)."""
    loc = scene.location
    key = (scene.time.utc, loc.lat, loc.lon, loc.altitude, scene.time.sun_override)
    return SETUP.get("celestial", key, lambda: _sun_and_moon(scene))


def _sun_and_moon(scene: Scene) -> SunMoon:
    loc = scene.location
    state = _celestial_state(scene.time.utc, loc.lat, loc.lon, loc.altitude)
    sun_el, sun_az = state.sun_elevation, state.sun_azimuth
    if scene.time.sun_override is not None:
        sun_el, sun_az = scene.time.sun_override.elevation, scene.time.sun_override.azimuth
    return SunMoon(sun_el, sun_az % 360.0, state.moon_elevation, state.moon_azimuth, state.moon_phase)


class FrameState:
    """What the renderer keeps between frames for the atmosphere and the eye: the eased fog/haze
    density, the exposure adaptation (both driven by sim_time deltas) and the last frame's meter
    cells, which a stream's next frame meters (post/meter_lag.py)."""

    def __init__(self):
        self.haze = HazeTransition()
        self.eye = EyeAdaptation()
        self.meter = MeterLag()


@dataclass
class FrameContext:
    ctx: moderngl.Context
    scene: Scene
    view: CameraView
    celestial: SunMoon
    light: Daylight
    exposure: float
    lights: list[PointLight]
    uniforms: dict = field(default_factory=dict)
    ev100: float = 0.0  # exposure used (EV100)
    illuminance_lux: float = 0.0  # natural horizontal illuminance at the camera
    # cd/m^2, mean luminance of the view the exposure adapts to (in a stream: the previous frame's view,
    # post/meter_lag.py)
    meter_luminance: float = 0.0
    # Shared resources the passes hand each other (e.g. "scene_distance": the copied distance texture).
    resources: dict = field(default_factory=dict)
    # Quality level in force (presets.knobs(pipeline, frame.quality)): a level name or an auto rung.
    quality: object = "medium"
    # Compile-time switches of the lit passes' shaders for this frame (light_defines).
    defines: dict = field(default_factory=dict)

    @property
    def camera_altitude(self) -> float:
        return self.scene.location.altitude + float(self.view.position[2])


# Local lights meter brighter on the surfaces they light than at the camera: the lit ground near a
# fire is a few times closer to it than the camera usually is.
LIGHT_METER_GAIN = 4.0


def local_light_illuminance(lights: list[PointLight], view) -> float:
    e = 0.0
    for light in lights:
        d2 = float(np.sum(view.relative(light.position) ** 2))
        e += float(LUMA @ np.asarray(light.color)) / max(d2, 1.0)
    return e


def meter_samples(sky: SkyFrame, scene: Scene, view, celestial, haze_height_m: float,
                  lights: list[PointLight]) -> np.ndarray:
    """Luminance samples (cd/m^2) of the view on a 16 x 9 grid for the exposure (post/exposure.py):
    sky directions from the sky-view table seen through the fog layer; ground as its base colour
    under the horizontal illuminance; sea as the Fresnel-weighted reflected sky (~5 %); plus local
    lights' illuminance near the camera on the ground."""
    albedo = float(LUMA @ np.asarray(scene.ground.color)) if scene.ground.enabled else GROUND_REFLECTANCE
    e_local = LIGHT_METER_GAIN * local_light_illuminance(lights, view)
    ground = albedo * (sky.horizontal_illuminance + e_local) / np.pi
    n, is_sky, sky_lum, refl = _view_sky_samples(sky, scene, view, celestial, haze_height_m)
    lum = np.full(n, ground)
    if sky_lum is not None:
        lum[is_sky] = sky_lum
    if refl is not None:
        lum[~is_sky] = 0.05 * refl + 0.02 * (sky.horizontal_illuminance + e_local) / np.pi
    return lum


_view_sky_cache: dict = {}


def _view_sky_samples(sky: SkyFrame, scene: Scene, view, celestial, haze_height_m: float):
    """The light-independent part of meter_samples: (sample count, sky mask, sky luminances seen
    through the fog, mirrored-sky luminances for the sea), memoised on its exact inputs (the view's
    basis and frustum, the filled sky-view table, the fog layer, sun and moon)."""
    sv = sky.sky_view
    have_table = sv is not None and sv.radiance_host is not None
    haze = sky.haze
    u = sky.uniforms
    key = None
    if have_table:
        key = (id(sv), sv._key, sv.fills, np.asarray(view.rotation, np.float64).tobytes(), tuple(view.tangents),
               u["u_sky_view_sun_h"], u["u_horizon_elevation"], haze_height_m, bool(scene.ocean.enabled),
               None if haze is None else (haze.key, u["u_haze_sun"], u["u_haze_moon"], u["u_haze_sky"]),
               _vec3(celestial.sun_dir), _vec3(celestial.moon_dir))
        hit = _view_sky_cache.get(key)
        if hit is not None:
            return hit
    dirs = frustum_directions(view)
    if not have_table:
        return len(dirs), None, None, None
    is_sky = dirs[:, 2] > u["u_horizon_elevation"]
    sky_lum = refl = None
    if np.any(is_sky):
        d = dirs[is_sky]
        clear = sv.luminance(d, u["u_sky_view_sun_h"], u["u_horizon_elevation"])
        if haze is not None and haze.beta[1] > 0.0:
            tau = haze.tau_view(haze_height_m, d)
            sun_n = np.asarray(u["u_haze_sun"]); moon_n = np.asarray(u["u_haze_moon"])
            flux = haze.fluxes(haze_height_m, sun_n, float(celestial.sun_dir[2]), np.asarray(u["u_haze_sky"]),
                               moon_n, float(celestial.moon_dir[2]))
            src = haze.source(haze_height_m, d, flux, celestial.sun_dir, sun_n, celestial.moon_dir, moon_n)
            t = np.exp(-np.minimum(tau, 80.0))
            clear = clear * (t @ LUMA) + (src * (1.0 - t)) @ LUMA
        sky_lum = clear
    if scene.ocean.enabled and np.any(~is_sky):
        mirrored = dirs[~is_sky] * np.array([1.0, 1.0, -1.0])
        refl = sv.luminance(mirrored, u["u_sky_view_sun_h"], u["u_horizon_elevation"])
    out = (len(dirs), is_sky, sky_lum, refl)
    for a in out[1:]:
        if a is not None:
            a.flags.writeable = False
    if len(_view_sky_cache) > 64:
        _view_sky_cache.clear()
    _view_sky_cache[key] = out
    return out


# What the frame setup derives from the world and keeps until its inputs change (memo.py): the
# camera's view, the uniforms of the view and of the sky's light.
SETUP = Memo()


def frame_view(camera, zero_to_one_depth: bool) -> tuple[CameraView, dict]:
    """make_view and the view's uniforms, kept while the camera record and the depth range are the
    same (a still camera: one view object, its cull planes computed once). Its arrays are read-only."""
    def compute():
        view = make_view(camera, zero_to_one_depth)
        for a in (view.position, view.rotation, view.view, view.projection):
            a.flags.writeable = False
        return view, _view_uniforms(view, camera)
    return SETUP.get("view", (camera, zero_to_one_depth), compute)


def build_frame(ctx: moderngl.Context, scene: Scene, state: FrameState | None = None) -> FrameContext:
    """Per-frame data. ``state`` (the renderer's) eases fog changes and adapts the exposure over
    sim_time; without it the frame shows the steady state of its scene."""
    view, view_uniforms = frame_view(scene.camera, zero_to_one(ctx))
    celestial = sun_and_moon(scene)
    altitude = scene.location.altitude + float(view.position[2])
    # Sky: resident atmosphere tables (units 12..15), fog layer, sky-view table (9..11), light.
    sky = sky_frame(ctx, scene, celestial, altitude, view.position[:2], state.haze if state else None)
    light = sky.light
    lights = FrameLights(gather_lights(scene, view, MAX_LIGHTS))
    # Provisional exposure for the passes (pre-exposure keeps half floats in range): the view
    # estimated from the sky-view table; the post pass meters the rendered frame and corrects it.
    samples = meter_samples(sky, scene, view, celestial, altitude - scene.location.altitude, lights)
    # the solve per exact samples: a view whose light does not flicker meters the same every frame
    target, meter = SETUP.get("meter_target", samples.tobytes(), lambda: display_metered_ev100(samples))
    ev100 = provisional_ev100(scene, state, target)
    frame = FrameContext(ctx, scene, view, celestial, light, exposure_of_ev100(ev100), lights,
                         ev100=ev100, illuminance_lux=sky.horizontal_illuminance, meter_luminance=meter)
    frame.resources["atmosphere_tables"] = sky.tables
    frame.resources["sky_view"] = sky.sky_view
    frame.resources["haze"] = sky.haze
    frame.resources["frame_state"] = state
    frame.resources["meter_samples"] = samples  # channels meter the union of their views (render/multiview.py)
    frame.uniforms = common_uniforms(frame, view_uniforms)
    frame.uniforms.update(sky.uniforms)
    lights.tiled = LightTiles.get(ctx).update(frame.uniforms)  # the view's tile light lists
    frame.defines = light_defines(celestial, lights)
    FrameBlock.get(ctx).update(frame.uniforms)
    return frame


def provisional_ev100(scene: Scene, state: FrameState | None, target: float) -> float:
    """The passes' exposure before the post pass meters the frame: the camera's fixed EV100, or
    ``target`` (estimated from the sky-view table) eased by the adaptation state."""
    if scene.camera.exposure_ev is not None:
        ev100 = float(scene.camera.exposure_ev)
    elif state is not None and state.eye.ev100 is not None and 0.0 < scene.time.sim_time - state.eye.sim_time <= 1.0:
        ev100 = 0.5 * (target + state.eye.ev100)  # mid-adaptation: between the last and the target
    else:
        ev100 = target
    return ev100


def set_exposure(frame: FrameContext, ev100: float, meter_luminance: float) -> None:
    """Give ``frame`` another provisional exposure (the frame block is written by the caller)."""
    frame.ev100 = ev100
    frame.exposure = exposure_of_ev100(ev100)
    frame.meter_luminance = meter_luminance
    frame.uniforms["u_exposure"] = frame.exposure
    frame.uniforms["u_adaptation_luminance"] = float(meter_luminance)


# common/lights.glsl skips the sun's or moon's term below this direction z (about -5.7 deg).
BODY_TERM_MIN_Z = -0.1


def light_defines(celestial: SunMoon, lights: list) -> dict:
    """SUN_TERM / MOON_TERM for common/lights.glsl: 0 when that body's term would be skipped at run
    time (same test, same float32 direction), so the frame's shaders do not carry its code;
    LOCAL_LIGHTS: 0 when the frame has no point or spot light; SPOT_LIGHTS: 0 when none of them is
    a spot; LIGHT_TILES: 1 when a pixel loops over its screen tile's lights (light_tiles.py). Passes
    that do not add these defines compile every term and test at run time."""
    sun_z = float(np.float32(celestial.sun_dir[2]))
    moon_z = float(np.float32(celestial.moon_dir[2]))
    return {"SUN_TERM": int(sun_z > BODY_TERM_MIN_Z), "MOON_TERM": int(moon_z > BODY_TERM_MIN_Z),
            **local_light_defines(lights)}


def local_light_defines(lights: list) -> dict:
    """The part of light_defines for passes that read point and spot lights only (light_illuminance:
    the sea, precipitation), so a sunset does not recompile them."""
    return {"LOCAL_LIGHTS": int(bool(lights)), "SPOT_LIGHTS": int(any(l.spot_dir is not None for l in lights)),
            "LIGHT_TILES": int(bool(lights) and getattr(lights, "tiled", False))}


def pixel_angle(camera) -> float:
    """Vertical angle (rad) one pixel covers at the centre of the view."""
    if camera.frustum is not None:
        span = math.tan(math.radians(camera.frustum.top)) - math.tan(math.radians(camera.frustum.bottom))
    else:
        span = 2.0 * math.tan(math.radians(camera.fov_y) / 2.0)
    return span / camera.height


def _vec3(v) -> tuple[float, float, float]:
    return tuple(float(x) for x in v)


def common_uniforms(frame: FrameContext, view_uniforms: dict | None = None) -> dict:
    """The frame's uniforms but the sky's; ``view_uniforms``: the view's part, when already made."""
    view, light = frame.view, frame.light
    light_key = (tuple(v.tobytes() if isinstance(v, np.ndarray) else v for v in vars(light).values()), frame.celestial)
    return {
        **(view_uniforms if view_uniforms is not None else _view_uniforms(view, frame.scene.camera)),
        **SETUP.get("light_uniforms", light_key, lambda: _light_uniforms(light, frame.celestial)),
        "u_camera_altitude": frame.camera_altitude,
        "u_exposure": frame.exposure,
        "u_adaptation_luminance": float(frame.meter_luminance),
        **light_uniforms(frame.lights, view, MAX_LIGHTS),
    }


def _view_uniforms(view: CameraView, camera) -> dict:
    return {
        "u_view_proj": gl_matrix(view.view_proj),
        "u_inv_view_proj": gl_matrix(np.linalg.inv(view.view_proj)),  # float64 inverse, finite depths
        "u_camera_right": _vec3(view.rotation[:, 0]),
        "u_camera_up": _vec3(view.rotation[:, 2]),
        "u_camera_forward": _vec3(view.rotation[:, 1]),
        "u_frustum_tangents": tuple(float(t) for t in view.tangents),
        "u_resolution": (float(view.width), float(view.height)),
        "u_view_pixel_angle": pixel_angle(camera),
    }


def _light_uniforms(light: Daylight, celestial: SunMoon) -> dict:
    return {
        "u_sun_dir": _vec3(celestial.sun_dir),
        "u_sun_illuminance": _vec3(light.sun_illuminance),
        "u_moon_dir": _vec3(celestial.moon_dir),
        "u_moon_illuminance": _vec3(light.moon_illuminance),
        "u_moon_phase": celestial.moon_phase,
        "u_sky_ambient": _vec3(light.sky_ambient),
        "u_sky_zenith": _vec3(light.zenith),
        "u_sky_horizon": _vec3(light.horizon),
        "u_sky_below": _vec3(light.below),
        "u_halo_color": _vec3(light.halo),
        "u_halo_exponent": light.halo_exponent,
        "u_sun_disk_cos": math.cos(SUN_ANGULAR_RADIUS),
        "u_sun_disk_luminance": _vec3(light.sun_disk_luminance),
        "u_fog_color": _vec3(light.horizon),
        "u_fog_scale_height": 1200.0,
    }
