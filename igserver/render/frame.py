"""Per-frame data every pass reads: the scene, the camera view, light, exposure, targets."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import moderngl
import numpy as np

from ..astro import celestial_state, direction_enu
from ..scene.model import Scene
from .camera import CameraView, gl_matrix, make_view
from .depth import zero_to_one
from .lights import PointLight, gather_lights, light_uniforms
from .sky.daylight import SUN_ANGULAR_RADIUS, Daylight
from .sky.frame_sky import sky_frame

# Point/spot lights per frame (uniform arrays in common/lights.glsl, which must match): the
# brightest at the camera first. The light loop skips lights out of range, so the cost per pixel
# is bounded by MAX_LIGHTS and usually far below it.
MAX_LIGHTS = 64


@dataclass(frozen=True)
class SunMoon:
    sun_elevation: float
    sun_azimuth: float
    moon_elevation: float
    moon_azimuth: float
    moon_phase: float

    @property
    def sun_dir(self) -> np.ndarray:
        return np.array(direction_enu(self.sun_elevation, self.sun_azimuth))

    @property
    def moon_dir(self) -> np.ndarray:
        return np.array(direction_enu(self.moon_elevation, self.moon_azimuth))


def sun_and_moon(scene: Scene) -> SunMoon:
    """From the ephemeris, or the instructor's fixed sun (the moon stays on the ephemeris)."""
    loc = scene.location
    state = celestial_state(scene.time.utc, loc.lat, loc.lon, loc.altitude)
    sun_el, sun_az = state.sun_elevation, state.sun_azimuth
    if scene.time.sun_override is not None:
        sun_el, sun_az = scene.time.sun_override.elevation, scene.time.sun_override.azimuth
    return SunMoon(sun_el, sun_az % 360.0, state.moon_elevation, state.moon_azimuth, state.moon_phase)


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
    # Shared resources the passes hand each other (e.g. "scene_distance": the copied distance texture).
    resources: dict = field(default_factory=dict)
    # Quality level in force (presets.knobs(pipeline, frame.quality)): a level name or an auto rung.
    quality: object = "medium"

    @property
    def camera_altitude(self) -> float:
        return self.scene.location.altitude + float(self.view.position[2])


# Local lights meter brighter on the surfaces they light than at the camera: the lit ground near a
# fire is a few times closer to it than the camera usually is.
LIGHT_METER_GAIN = 4.0


def auto_ev100(daylight_ev100: float, lights: list[PointLight], view) -> float:
    """Automatic exposure: the daylight's EV100 raised by the illuminance local lights (fires,
    lamps) cast near the camera, so a night fire is exposed like a camera operator would."""
    e_lights = 0.0
    for light in lights:
        d2 = float(np.sum(view.relative(light.position) ** 2))
        e_lights += float(np.dot([0.2126, 0.7152, 0.0722], light.color)) / max(d2, 1.0)
    # EV100 = log2(E * S / C) with S = 100, C = 250 (incident-light meter)
    return math.log2(2.0**daylight_ev100 + LIGHT_METER_GAIN * e_lights * 100.0 / 250.0)


def build_frame(ctx: moderngl.Context, scene: Scene) -> FrameContext:
    view = make_view(scene.camera, zero_to_one(ctx))
    celestial = sun_and_moon(scene)
    altitude = scene.location.altitude + float(view.position[2])
    # Sky: resident atmosphere tables (bound on units 12..15), the light they imply, sky uniforms.
    sky = sky_frame(ctx, scene, celestial, altitude, view.position[:2])
    light = sky.light
    lights = gather_lights(scene, view, MAX_LIGHTS)
    exposure = light.exposure(scene.camera.exposure_ev if scene.camera.exposure_ev is not None
                              else auto_ev100(light.ev100, lights, view))
    frame = FrameContext(ctx, scene, view, celestial, light, exposure, lights)
    frame.resources["atmosphere_tables"] = sky.tables
    frame.uniforms = common_uniforms(frame)
    frame.uniforms.update(sky.uniforms)
    return frame


def _vec3(v) -> tuple[float, float, float]:
    return tuple(float(x) for x in v)


def common_uniforms(frame: FrameContext) -> dict:
    view, light, scene = frame.view, frame.light, frame.scene
    visibility = scene.atmosphere.visibility
    return {
        "u_view_proj": gl_matrix(view.view_proj),
        "u_inv_view_proj": gl_matrix(np.linalg.inv(view.view_proj)),  # float64 inverse, finite depths
        "u_camera_right": _vec3(view.rotation[:, 0]),
        "u_camera_up": _vec3(view.rotation[:, 2]),
        "u_camera_forward": _vec3(view.rotation[:, 1]),
        "u_frustum_tangents": tuple(float(t) for t in view.tangents),
        "u_resolution": (float(view.width), float(view.height)),
        "u_camera_altitude": frame.camera_altitude,
        "u_exposure": frame.exposure,
        "u_sun_dir": _vec3(frame.celestial.sun_dir),
        "u_sun_illuminance": _vec3(light.sun_illuminance),
        "u_moon_dir": _vec3(frame.celestial.moon_dir),
        "u_moon_illuminance": _vec3(light.moon_illuminance),
        "u_moon_phase": frame.celestial.moon_phase,
        "u_sky_ambient": _vec3(light.sky_ambient),
        "u_sky_zenith": _vec3(light.zenith),
        "u_sky_horizon": _vec3(light.horizon),
        "u_sky_below": _vec3(light.below),
        "u_halo_color": _vec3(light.halo),
        "u_halo_exponent": light.halo_exponent,
        "u_sun_disk_cos": math.cos(SUN_ANGULAR_RADIUS),
        "u_sun_disk_luminance": _vec3(light.sun_disk_luminance),
        "u_fog_color": _vec3(light.horizon),
        "u_fog_beta": 3.912 / visibility,  # Koschmieder: contrast 2 % at the visibility distance
        "u_fog_scale_height": 1200.0,
        **light_uniforms(frame.lights, view, MAX_LIGHTS),
    }
