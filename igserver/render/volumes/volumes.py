"""Volumes pass: fire and smoke effects, modelled into 3D textures and ray-marched (DESIGN §4.3).

Per visible volume (effects.visible_volumes: active or fading, non-zero size, in the frustum):
  1. modelling: a compute shader writes the effect's 3D texture (rgba16f, colour + density) from
     its revolved profile and the turbulence; 2. rendering: the box's back faces are drawn into
     the HDR colour with premultiplied blending; each fragment marches the texture (march.frag.glsl)
     and stops at the copied scene distance.

When the modelling stage runs: the texture depends on the effect's parameters and on the noise
scroll tau (sim_time). It is re-modelled only when that state changed since the last frame, so
repeated frames of one state (several channels, a paused simulation, the quality study) cost only
the march; while time runs, every frame re-models (the turbulence moves). Its resolution is the
smaller of the quality knob and the container's size on screen (about one voxel per 1.5 pixels),
so far-away fires cost a few thousand voxels.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass

import moderngl
import numpy as np

from ...assets import AssetError, resolve_asset
from ...scene.model import Scene
from ..camera import CameraView
from ..passes import RenderPass
from ..shaders import set_uniforms
from .effects import NOISE_PERIOD, NOISE_SCALE, Volume, visible_volumes
from .fire_lights import fire_light
from .profiles import FIRE_SMOKE_ALBEDO, SMOKE_ALBEDO, load_profile

MAX_PROFILE_TEXTURES = 32  # profile textures kept resident (LRU); each is small, their number is not
FIRE_LUMINANCE = 2.0e4  # cd/m^2 of profile colour 1 at intensity 1 (a candle is ~1e4, large flames more)
FIRE_SIGMA_D = 1.5  # extinction of fire density 1 times the diameter: optical depth across the core
SMOKE_SIGMA_D = 3.0
ROUGHNESS = {"fire": 0.6, "gas_burner": 0.12, "smoke": 0.35}
EVICT_AFTER_FRAMES = 120


@dataclass(frozen=True)
class VolumeSettings:
    steps: int = 64  # samples along the container's diagonal
    octaves: int = 3  # turbulence octaves (2-4 in the paper)
    resolution: int = 32  # voxels across the container's diameter (height: in proportion)
    min_resolution: int = 8
    lod: bool = True  # lower the resolution for containers small on screen (off: the knob itself)


# Quality presets: points on the measured curve (igserver quality volumes, close night fire at
# 640x360 on llvmpipe; errors in 8-bit sRGB levels vs 1024 steps / 4 octaves / 128 voxels):
#   low    32 / 2 / 16: rmse ~9.5, banding ~3.9, ~40 ms
#   medium 48 / 3 / 32: rmse ~5.5, banding ~1.9, ~90 ms  (the knee: banding < 2 levels)
#   high  128 / 4 / 64: rmse ~1.6, banding ~0.5, ~220-440 ms (the 64-voxel modelling dominates)
# Octaves matter least (the 4th octave has weight 1/8); steps and texture size trade together:
# a sharper texture needs more steps or it aliases (16 steps: error grows with resolution).
PRESETS = {
    "low": VolumeSettings(steps=32, octaves=2, resolution=16),
    "medium": VolumeSettings(steps=48, octaves=3, resolution=32),
    "high": VolumeSettings(steps=128, octaves=4, resolution=64),
}


def volumes_needed(scene: Scene, view: CameraView) -> bool:
    return bool(scene.effects) and bool(visible_volumes(scene, view))


def texture_size(vol: Volume, view: CameraView, settings: VolumeSettings) -> tuple[int, int, int]:
    """(x, y, z) voxels: the knob, lowered for containers that are small on screen."""
    distance = max(float(np.linalg.norm(view.relative(vol.bounding_sphere[0]))) - vol.bounding_sphere[1], 1e-3)
    pixels_per_m = view.projection[1, 1] * view.height / 2.0 / distance
    across = 2.0 * vol.radius * pixels_per_m / 1.5  # about one voxel per 1.5 px
    res_xy = settings.resolution
    if settings.lod:
        res_xy = int(min(res_xy, max(settings.min_resolution, 2 ** round(math.log2(max(across, 1.0))))))
    aspect = vol.height / max(2.0 * vol.radius, 1e-6)
    res_z = int(min(max(round(res_xy * aspect), settings.min_resolution), 4 * res_xy))
    return res_xy, res_xy, res_z


class _Slot:
    """An effect's 3D texture and the state it was modelled for."""

    def __init__(self):
        self.texture: moderngl.Texture | None = None
        self.size: tuple[int, int, int] | None = None
        self.state: tuple | None = None
        self.last_frame = 0


def _unit_cube_corners() -> np.ndarray:
    """36 vertices of [0,1]^3, counter-clockwise seen from outside."""
    c = np.array([[x, y, z] for z in (0, 1) for y in (0, 1) for x in (0, 1)], dtype=np.float32)
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    tris = [c[[a, b, cc, a, cc, d]] for a, b, cc, d in quads]
    return np.concatenate(tris).astype(np.float32)


class VolumesPass(RenderPass):
    name = "volumes"
    reads_scene_distance = True

    def __init__(self, ctx, programs):
        super().__init__(ctx, programs)
        self.settings: VolumeSettings | None = None  # None = the scene's quality preset
        self.stats = {"modelled": 0, "drawn": 0, "voxels": 0}
        self._slots: dict[tuple, _Slot] = {}
        self._profiles: OrderedDict[tuple, moderngl.Texture] = OrderedDict()  # LRU, at most MAX_PROFILE_TEXTURES
        self._cube_vbo = None
        self._vaos: dict = {}
        self._frame = 0

    def needed(self, scene: Scene, view: CameraView) -> bool:
        return volumes_needed(scene, view)

    # -- modelling ---------------------------------------------------------------------------

    def _profile_texture(self, vol: Volume) -> moderngl.Texture:
        """The profile's texture, from a bounded LRU cache: hosts naming many distinct profiles cannot grow
        memory. ``vol.profile`` is an asset name (validated by the scene model); it is resolved again here,
        in the render process, so only a regular file inside the profiles directory is ever opened."""
        key = (vol.kind, vol.profile)
        tex = self._profiles.get(key)
        if tex is not None:
            self._profiles.move_to_end(key)
            return tex
        path = None
        if vol.profile is not None:
            try:
                path = str(resolve_asset("profiles", vol.profile, (".png",)))
            except AssetError:  # removed since the state was accepted: the procedural profile
                path = None
        data = load_profile(vol.kind, path)
        tex = self.ctx.texture((data.shape[1], data.shape[0]), 4, data.astype("f2").tobytes(), dtype="f2")
        tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
        tex.repeat_x = tex.repeat_y = False
        self._profiles[key] = tex
        while len(self._profiles) > MAX_PROFILE_TEXTURES:
            self._profiles.popitem(last=False)[1].release()
        return tex

    def _model(self, vol: Volume, frame, settings: VolumeSettings) -> moderngl.Texture:
        scene = frame.scene
        slot = self._slots.setdefault(vol.key, _Slot())
        slot.last_frame = self._frame
        size = texture_size(vol, frame.view, settings)
        tau = vol.noise_offset(scene.time.sim_time)
        smoke = vol.kind == "smoke"
        sun = tuple(float(x) for x in frame.celestial.sun_dir) if smoke else None
        state = (size, tau, settings.octaves, vol.radius, vol.height, vol.opacity, vol.seed, vol.kind,
                 vol.profile, vol.effect.diameter, vol.effect.intensity, sun)
        if slot.state == state and slot.texture is not None:
            return slot.texture
        if slot.size != size:
            if slot.texture is not None:
                slot.texture.release()
            slot.texture = self.ctx.texture3d(size, 4, dtype="f2")
            slot.texture.filter = (moderngl.LINEAR, moderngl.LINEAR)
            slot.texture.repeat_x = slot.texture.repeat_y = slot.texture.repeat_z = False
            slot.size = size
        program = self.programs.compute("volumes/model.comp.glsl", {"SMOKE": 1} if smoke else None)
        sigma = (SMOKE_SIGMA_D if smoke else FIRE_SIGMA_D) / max(vol.effect.diameter, 1e-3)
        set_uniforms(program, {
            "u_size": size,
            "u_extent": (vol.radius, vol.radius, vol.height),
            "u_wavelength": vol.nominal_radius / NOISE_SCALE,
            "u_tau": tau,
            "u_period": NOISE_PERIOD,
            "u_roughness": ROUGHNESS[vol.kind],
            "u_octaves": settings.octaves,
            "u_seed": vol.seed & 0xFFFFFFFF,
            "u_opacity": vol.opacity,
            "u_cooling": 0.0 if vol.effect.active else 1.0 - vol.level,
            "u_sun_local": sun or (0.0, 0.0, 1.0),
            "u_sigma": sigma,
            "u_profile": 0,
        })
        self._profile_texture(vol).use(0)
        slot.texture.bind_to_image(0, read=False, write=True)
        program.run(*(math.ceil(s / 4) for s in size))
        self.ctx.memory_barrier()
        slot.state = state
        self.stats["modelled"] += 1
        self.stats["voxels"] += size[0] * size[1] * size[2]
        return slot.texture

    # -- rendering ---------------------------------------------------------------------------

    def _vao(self, program):
        if self._cube_vbo is None:
            self._cube_vbo = self.ctx.buffer(_unit_cube_corners().tobytes())
        vao = self._vaos.get(id(program))
        if vao is None:
            vao = self.ctx.vertex_array(program, [(self._cube_vbo, "3f", "in_position")])
            self._vaos[id(program)] = vao
        return vao

    def execute(self, frame, targets) -> None:
        scene, view = frame.scene, frame.view
        settings = self.settings or PRESETS[scene.quality.preset]
        self._frame += 1
        self.stats = {"modelled": 0, "drawn": 0, "voxels": 0}
        volumes = visible_volumes(scene, view)
        textures = [self._model(vol, frame, settings) for vol in volumes]

        targets.color_fbo.use()
        self.ctx.disable(moderngl.DEPTH_TEST)
        self.ctx.enable(moderngl.BLEND | moderngl.CULL_FACE)
        self.ctx.front_face = "ccw"
        self.ctx.cull_face = "front"
        self.ctx.blend_func = moderngl.ONE, moderngl.ONE_MINUS_SRC_ALPHA
        distance = frame.resources["scene_distance"]
        distance.use(1)
        jitter_offset = (scene.host_frame * 0.6180339887) % 1.0  # golden-ratio sequence per frame
        for vol, tex in zip(volumes, textures):
            smoke = vol.kind == "smoke"
            program = self.programs.program("volumes/march.vert.glsl", "volumes/march.frag.glsl",
                                            {"SMOKE": 1} if smoke else None)
            set_uniforms(program, frame.uniforms)
            lo, hi = vol.box
            uniforms = {
                "u_volume": 0, "u_scene_distance": 1,
                "u_box_min": tuple(float(x) for x in view.relative(lo)),
                "u_box_max": tuple(float(x) for x in view.relative(hi)),
                "u_base": tuple(float(x) for x in view.relative(vol.base)),
                "u_extent": (vol.radius, vol.radius, vol.height),
                "u_lean": (float(vol.lean[0]), float(vol.lean[1])),
                "u_steps": settings.steps,
                "u_sigma": (SMOKE_SIGMA_D if smoke else FIRE_SIGMA_D) / max(vol.effect.diameter, 1e-3),
                "u_jitter_offset": jitter_offset,
            }
            if smoke:
                uniforms["u_hg_g"] = 0.6
                glow = fire_light(vol.effect, scene) if vol.effect.type == "fire" else None
                uniforms["u_glow_pos"] = tuple(float(x) for x in view.relative(glow.position)) if glow else (0.0, 0.0, 0.0)
                uniforms["u_glow_intensity"] = tuple(float(x) for x in glow.color) if glow else (0.0, 0.0, 0.0)
                # sooty smoke of a fire vs. a light grey smoke generator: scale the profile's albedo
                sooty = vol.effect.type == "fire" and vol.profile is None
                uniforms["u_albedo_scale"] = FIRE_SMOKE_ALBEDO / SMOKE_ALBEDO if sooty else 1.0
            else:
                lum = FIRE_LUMINANCE * math.sqrt(vol.intensity)
                uniforms["u_emission"] = (lum, lum, lum)
            set_uniforms(program, uniforms)
            tex.use(0)
            self._vao(program).render(moderngl.TRIANGLES)
            self.stats["drawn"] += 1
        self.ctx.disable(moderngl.BLEND | moderngl.CULL_FACE)
        self.ctx.cull_face = "back"
        self._evict()

    def _evict(self) -> None:
        """Free the textures of effects not seen for a while (gone, out of view, inactive)."""
        for key in [k for k, s in self._slots.items() if self._frame - s.last_frame > EVICT_AFTER_FRAMES]:
            if self._slots[key].texture is not None:
                self._slots[key].texture.release()
            del self._slots[key]


__all__ = ["VolumesPass", "VolumeSettings", "PRESETS", "volumes_needed", "texture_size"]
