"""Volumes pass: fire and smoke effects, modelled into 3D textures and ray-marched (docs/design.md#fire-and-smoke).

Per visible volume (effects.visible_volumes: active or fading, non-zero size, in the frustum):
  1. modelling: a compute shader writes the effect's 3D texture (rgba16f, colour + density) from
     its revolved profile and the turbulence; 2. rendering: the back faces of the container's slabs
     are drawn into the HDR colour with premultiplied blending (one instanced draw a volume, its
     constants one record of the march block: march.py MarchPlan, march_block.py); each fragment
     marches the texture (march.frag.glsl) and stops at the copied scene distance.

When the modelling stage runs: the texture depends on the effect's parameters and on the noise
scroll tau (sim_time). It is re-modelled only when that state changed since the last frame, so
repeated frames of one state (several channels, a paused simulation, the quality study) cost only
the march. While time runs, the turbulence moves: with ``model_hz`` = 0 every frame re-models at
its exact tau; with a capped rate (``model_hz`` > 0) the textures are keyframes at sim times
k / rate, two are kept (k and k + 1) and the march blends them by the fraction of the period
elapsed, so a 30 Hz host pays one modelling every 30 / rate frames and the motion stays
continuous (a parameter change, e.g. a fade, is picked up at the next keyframe and blends in).
Its resolution is the smaller of the quality knob and the container's size on screen (about one
voxel per 1.5 pixels), so far-away fires cost a few thousand voxels.

Reduced-resolution march (``scale`` 2 or 4): the scene distance is reduced to the nearest of each
block (downsample.frag.glsl), the volumes are marched into a low-resolution premultiplied target,
and a depth-aware upsampling blends it into the frame (upsample.frag.glsl). When the scale changes
in a running stream (the auto preset moving a rung), the old and new marches are both drawn for
SCALE_FADE_FRAMES frames, each pixel showing one of them by a fixed dither against a weight going
from the old to the new (a dissolve), so the switch fades instead of popping.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass

import moderngl
import numpy as np

from ..bindings import BLOCKS, use_texture, write_buffer
from ...assets import AssetError, resolve_asset
from ...effect_kinds import EFFECT_KINDS
from ...scene.model import Scene
from .. import presets
from ..camera import CameraView
from ..memo import Memo, view_key
from ..passes import RenderPass
from ..post.exposure import MAX_STREAM_DT
from ..texture_pool import TexturePool
from ..shaders import set_uniforms
from .effects import NOISE_PERIOD, NOISE_SCALE, Volume, fade_level, visible_volumes
from . import march_block
from .fire_lights import flame_light
from .march import MarchPlan, extinction, footprint_scale, scattering, texture_size
from .profiles import load_profile

MAX_SHADOW_TEXTURES = 3  # per smoke effect: the keyframes in flight (k, k + 1, k + 2) may differ in a fade
MAX_PROFILE_TEXTURES = 32  # profile textures kept resident (LRU); each is small, their number is not
PUFF_AMPLITUDE = 0.25  # a puffing flame's necks and bulges: its radius x (1 +- 0.25)
EVICT_AFTER_FRAMES = 120
SCALE_FADE_FRAMES = 8  # frames over which a changed march resolution cross-fades (~0.27 s at 30 Hz)


@dataclass(frozen=True)
class VolumeSettings:
    steps: int = 64  # samples along the container's diagonal (the step is at most one voxel)
    octaves: int = 3  # turbulence octaves (2-4 in the paper)
    resolution: int = 32  # voxels across the container's diameter (height: in proportion)
    min_resolution: int = 8
    lod: bool = True  # screen-size level of detail (off: the knobs themselves): a coarser texture for
    #                   containers small on screen, a coarser march where the voxels are large on it
    scale: int = 1  # march resolution divisor: 1 full, 2 half, 4 quarter (depth-aware upsampling);
    #                 with lod, the finest: raised up to MAX_MARCH_SCALE by footprint_scale()
    model_hz: float = 0.0  # re-modelling keyframes per second of sim time; 0 = every frame


# Quality presets: points on the measured curves (igserver quality volumes: close night fire on
# llvmpipe, errors in 8-bit sRGB levels against 1024 steps / 4 octaves / 128 voxels, full
# resolution, exact modelling time). What the curves showed:
#   * the modelling stage dominates while time runs: re-modelling at 5-10 Hz with keyframe
#     blending instead of every frame cut the pass 2-4x for +0.2..2.5 RMSE;
#   * half-resolution marching cuts the march ~3x for ~+1.5 levels of low-passed error; quarter
#     resolution shows blocks at fire edges (low only);
#   * steps matter little once the step follows the pixel footprint; octaves and the texture cap
#     hardly change the error of a fire seen from outside (3 -> 2 octaves: none measurable, -10 %
#     time; 32 -> 16 voxels: +0.4 lowpass, -30 % time), but from INSIDE a plume the picture is all
#     texture detail: lowpass error 22 (3 octaves, 32 voxels) -> 30 (2 octaves) -> 39 (24 voxels),
#     so medium keeps 3 / 32; a 64-voxel texture makes modelling and the voxel-limited near steps
#     dominate.
PRESETS = {
    "low": VolumeSettings(steps=32, octaves=2, resolution=16, scale=4, model_hz=5.0),
    "medium": VolumeSettings(steps=48, octaves=3, resolution=32, scale=2, model_hz=10.0),
    "high": VolumeSettings(steps=96, octaves=4, resolution=48, scale=1, model_hz=30.0),
}
presets.register("volumes", PRESETS)


def volumes_needed(scene: Scene, view: CameraView) -> bool:
    return bool(scene.effects) and bool(visible_volumes(scene, view))


# A soft part that moved this much since a keyframe was modelled is a jump (a host setting another time of
# day, a fire resized), not the drift of a running clock (the sun moves 0.0004 deg per 0.1 s keyframe, a
# fade a few per cent): the keyframe is modelled again now instead of showing the old state until sim_time
# reaches the next one, which a paused clock never does.
SOFT_JUMP_SUN_COS = math.cos(math.radians(1.0))
SOFT_JUMP_RELATIVE = 0.2


def _soft_jump(old: tuple, new: tuple) -> bool:
    """Whether the soft state ``new`` (radius, height, opacity, level, sun direction or None) jumped from
    ``old``, the one a keyframe was modelled with."""
    if old == new:
        return False
    old_sun, new_sun = old[-1], new[-1]
    if (old_sun is None) != (new_sun is None):
        return True
    if old_sun is not None and (old_sun[0] * new_sun[0] + old_sun[1] * new_sun[1]
                                + old_sun[2] * new_sun[2]) < SOFT_JUMP_SUN_COS:
        return True
    if old[:-1] == new[:-1]:  # (while time runs, only the sun moves)
        return False
    return any(abs(a - b) > SOFT_JUMP_RELATIVE * max(abs(a), abs(b), 1e-6) for a, b in zip(old[:-1], new[:-1]))


def model_octaves(vol: Volume, size: tuple[int, int, int], settings: VolumeSettings) -> int:
    """Turbulence octaves of a texture of ``size``: the knob's at its resolution, one fewer for
    smoke per halving below it (texture_size's LOD). Octave i's lattice is lambda / 2^i and the
    knob's texture holds about two voxels per lattice cell of its finest octave; a halved texture
    would sample that octave at one voxel per cell, aliasing it into a pattern that is not the
    turbulence's (sea_harbour_fire's plume, low-passed error over four sim times: 1.7-3.0 levels
    either way, 0.1 less on average with the octave dropped, and a third less noise to model).
    Flames keep the knob's: the octaves' sum sets how far the tips reach (v = z + roughness Turb
    sqrt(z))."""
    if not scattering(vol):
        return settings.octaves
    halvings = max(round(math.log2(max(settings.resolution, 1) / max(size[0], 1))), 0)
    return max(settings.octaves - halvings, 1)


class _Model:
    """One modelled 3D texture and the state (and keyframe) it was modelled for."""

    def __init__(self, texture: moderngl.Texture, size: tuple[int, int, int], pool: TexturePool):
        self.texture = texture
        self.size = size
        self.pool = pool
        self.state: tuple | None = None
        self.key: int | None = None  # keyframe index (capped rate), None = exact tau
        self.done_z = 0  # z slices modelled so far (a keyframe ahead is modelled over several frames)
        self.uniforms: dict | None = None  # the modelling inputs, frozen when its first slice was modelled
        self.smoke = False
        self.slot: "_Slot | None" = None
        self.vol: Volume | None = None  # the effect as it was when the first slice was modelled

    @property
    def complete(self) -> bool:
        return self.done_z >= self.size[2]

    def release(self) -> None:
        self.pool.give(self.texture)


class _Slot:
    """An effect's modelled textures: one (every frame) or two keyframes (capped rate)."""

    def __init__(self, pool: TexturePool):
        self.pool = pool
        self.models: list[_Model] = []
        self.last_frame = 0
        self.last_time: float | None = None  # sim_time of the last frame that used it
        self.shadows: OrderedDict[tuple, moderngl.Texture] = OrderedDict()  # smoke: inputs -> (t_sun, t_sky)

    def release(self) -> None:
        for m in self.models:
            m.release()
        self.models = []
        for tex in self.shadows.values():
            self.pool.give(tex)
        self.shadows.clear()


def _unit_cube_corners() -> np.ndarray:
    """36 vertices of [0,1]^3, counter-clockwise seen from outside."""
    c = np.array([[x, y, z] for z in (0, 1) for y in (0, 1) for x in (0, 1)], dtype=np.float32)
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    tris = [c[[a, b, cc, a, cc, d]] for a, b, cc, d in quads]
    return np.concatenate(tris).astype(np.float32)


class VolumesPass(RenderPass):
    name = "volumes"
    reads_scene_distance = True
    preset_pipeline = "volumes"
    view_state = ("_scale_state", "_fade")  # each view's march scale and its cross-fade (_layers)
    _scale_state = (None, None)
    _fade = None

    def __init__(self, ctx, programs):
        super().__init__(ctx, programs)
        self.memo = Memo()
        self.pool = TexturePool(ctx)  # keyframes' and smoke shadows' 3D textures, reused
        self.stats = {"modelled": 0, "drawn": 0, "voxels": 0}
        self._slots: dict[tuple, _Slot] = {}
        self._profiles: OrderedDict[tuple, moderngl.Texture] = OrderedDict()  # LRU, at most MAX_PROFILE_TEXTURES
        self._cube_vbo = None
        self._vaos: dict = {}
        self._frame = 0
        self._low: dict = {}  # size -> (colour, distance, colour fbo, distance fbo) of the reduced march
        self._low_last = None
        self._scale_state: tuple[int | None, float | None] = (None, None)  # last march scale, its sim_time
        self._fade: tuple[int, int] | None = None  # (old scale, frames left) of a running cross-fade
        self._model_inputs: dict = {}  # modelling program -> the model inputs (dict) last written to it
        self._programs: dict[tuple, object] = {}  # the pass's variants (_program)
        self._block = None  # the march plan's records (march_block.py), grown when a plan needs more
        self._block_align = int(ctx.info.get("GL_UNIFORM_BUFFER_OFFSET_ALIGNMENT", 256) or 256)

    def needed(self, scene: Scene, view: CameraView) -> bool:
        if not hasattr(self, "memo"):  # graph.plan_passes asks an instance made without a context
            return volumes_needed(scene, view)
        return bool(scene.effects) and bool(self._visible(scene, view)[1])

    def _visible(self, scene: Scene, view: CameraView) -> tuple[tuple, list]:
        """(key, visible_volumes): the volumes follow the effects, their fade levels now, the wind
        that bends them and the view; kept while those are the same (the frame graph asks before the
        pass draws)."""
        t = scene.time.sim_time
        key = (tuple(scene.effects), tuple(fade_level(e, t) for e in scene.effects), scene.weather.wind_speed,
               scene.weather.wind_direction, view_key(view))
        return key, self.memo.get("visible_volumes", key, lambda: visible_volumes(scene, view))

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

    @staticmethod
    def _static_state(plan: "MarchPlan", i: int, frame) -> tuple[tuple, tuple]:
        """Everything volume ``i``'s texture depends on except the noise scroll, as (hard, soft): a
        change of a hard part (texture size, octaves, the effect's parameters: MarchPlan) re-models
        at once; the soft part changes continuously while time runs (fade, the sun) and is picked up
        at the next keyframe of a capped rate, blending in."""
        sun = tuple(float(x) for x in frame.celestial.sun_dir) if plan.smoke[i] else None
        return plan.hard[i], (*plan.soft[i], sun)

    def _models_for(self, plan: "MarchPlan", i: int, frame, settings: VolumeSettings) -> tuple[moderngl.Texture, moderngl.Texture, float]:
        """(texture, next texture, blend weight of the next) of the plan's volume ``i`` for this
        frame, modelling what is missing."""
        vol, size = plan.volumes[i], plan.sizes[i]
        slot = self._slots.get(vol.key)
        if slot is None:
            slot = self._slots[vol.key] = _Slot(self.pool)
        slot.last_frame = self._frame
        static = self._static_state(plan, i, frame)
        sim_time = frame.scene.time.sim_time
        if settings.model_hz <= 0.0:
            state = (static, vol.noise_offset(sim_time), vol.puff_phase(sim_time))
            model = slot.models[0] if slot.models else None
            if model is None or model.state != state:
                model = self._model_into(slot, model, vol, frame, settings, size, sim_time)
                model.state, model.key = state, None
                slot.models = [model]
            return model.texture, model.texture, 0.0
        # Capped rate: keyframes k and k + 1 around sim_time (float64), blended by the fraction.
        period = 1.0 / settings.model_hz
        x = sim_time * settings.model_hz
        k = math.floor(x)
        if x - k > 1.0 - 1e-6:  # on a keyframe up to rounding (100 + 3/30 s at 10 Hz)
            k += 1
        blend = min(max(x - k, 0.0), 1.0)
        last_time, slot.last_time = slot.last_time, sim_time
        keep = [m for m in slot.models if m.key in (k, k + 1, k + 2) and m.state[0] == static[0]
                and not _soft_jump(m.state[1], static[1])]
        for m in slot.models:
            if m not in keep:
                m.release()
        slot.models = keep
        for key in (k, k + 1):
            model = next((m for m in slot.models if m.key == key), None)
            if model is None:  # (perhaps modelled already with the previous soft state: it blends in)
                model = self._new_model(vol, frame, settings, size, key * period)
                model.state, model.key = static, key
                slot.models.append(model)
            if not model.complete:  # a jump in time: what was modelled ahead is needed now
                self._model_slices(model, model.size[2])
        # The keyframe after next, spread over the frames until it is needed (when sim_time
        # reaches k + 1), so that no frame pays a whole keyframe: only while time runs forward
        # by less than a period per frame (a stream), from the frame rate seen so far.
        dx = (sim_time - last_time) * settings.model_hz if last_time is not None else 0.0
        if self.model_ahead and 0.0 < dx < 1.0 - 1e-6:  # (a frame per period or fewer: nothing to spread)
            ahead = next((m for m in slot.models if m.key == k + 2), None)
            if ahead is None:
                ahead = self._new_model(vol, frame, settings, size, (k + 2) * period)
                ahead.state, ahead.key = static, k + 2
                slot.models.append(ahead)
            frames_left = max(1, math.ceil((k + 1 - x) / dx - 1e-6))  # this frame and the next ones before k + 1
            self._model_slices(ahead, ahead.done_z + -(-(ahead.size[2] - ahead.done_z) // frames_left))
        slot.models.sort(key=lambda m: m.key)
        return slot.models[0].texture, slot.models[1].texture, blend

    model_ahead = True  # model the keyframe after next over the frames before it (off: when needed)

    def _model_into(self, slot: _Slot, model: "_Model | None", vol: Volume, frame, settings: VolumeSettings,
                    size, sim_time: float) -> _Model:
        """Run the whole modelling stage for ``sim_time`` into ``model``'s texture (or a new one)."""
        new = self._new_model(vol, frame, settings, size, sim_time, reuse=model)
        self._model_slices(new, size[2])
        return new

    def _new_model(self, vol: Volume, frame, settings: VolumeSettings, size, sim_time: float,
                   reuse: "_Model | None" = None) -> _Model:
        """A model of ``vol`` at ``sim_time`` with nothing modelled yet: its texture (``reuse``'s if
        the size fits) and the modelling inputs, frozen now so that slices modelled in later
        frames belong to the same keyframe."""
        if reuse is None or reuse.size != size:
            if reuse is not None:
                reuse.release()
            model = _Model(self.pool.take(size, 4, (moderngl.LINEAR, moderngl.LINEAR)), size, self.pool)
        else:
            model = reuse
        smoke = scattering(vol)
        sun = tuple(float(x) for x in frame.celestial.sun_dir) if smoke else None
        sigma = extinction(vol, smoke)
        model.done_z = 0
        model.smoke = smoke
        model.slot = self._slots[vol.key]
        model.vol = vol
        model.uniforms = {
            "u_size": size,
            "u_extent": (vol.radius, vol.radius, vol.height),
            "u_wavelength": vol.nominal_radius / NOISE_SCALE,
            "u_tau": vol.noise_offset(sim_time),
            "u_period": NOISE_PERIOD,
            "u_roughness": EFFECT_KINDS[vol.kind].roughness,
            "u_octaves": model_octaves(vol, size, settings),
            "u_seed": vol.seed & 0xFFFFFFFF,
            "u_opacity": vol.opacity,
            "u_cooling": 0.0 if vol.effect.active else 1.0 - vol.level,
            "u_sun_local": sun or (0.0, 0.0, 1.0),
            "u_sigma": sigma,
            "u_profile": 0,
            # A pool fire puffs: toroidal vortices shed at f = 1.5 / sqrt(D) rise at the flame's
            # buoyant speed w (Volume.rise_speed), so the necks and bulges are w / f apart.
            "u_puff": PUFF_AMPLITUDE if EFFECT_KINDS[vol.kind].container == "pool_fire" else 0.0,
            "u_puff_phase": vol.puff_phase(sim_time),
            "u_puff_wavenumber": vol.puff_wavenumber,
        }
        return model

    def _model_slices(self, model: _Model, z_end: int) -> None:
        """Model ``model``'s z slices from where it stopped up to ``z_end`` (rounded up to the
        compute group's 4 slices; the shader drops invocations past the texture)."""
        z0 = model.done_z
        z1 = min(z0 + -(-(max(z_end, z0) - z0) // 4) * 4, model.size[2])
        if z1 <= z0:
            return
        program = self._program(("model", model.smoke), lambda: self.programs.compute(
            "volumes/model.comp.glsl", {"SMOKE": 1} if model.smoke else None))
        if self._model_inputs.get(program) is not model.uniforms:  # (a new model's inputs are a new dict)
            set_uniforms(program, {**model.uniforms, "u_shadows": 1})
            self._model_inputs[program] = model.uniforms
        set_uniforms(program, {"u_z_first": z0})
        use_texture(self._profile_texture(model.vol), 0)
        if model.smoke:
            use_texture(self._shadows(model), 1)
        model.texture.bind_to_image(0, read=False, write=True)
        program.run(math.ceil(model.size[0] / 4), math.ceil(model.size[1] / 4), (z1 - z0) // 4 + ((z1 - z0) % 4 > 0))
        self.ctx.memory_barrier()
        model.done_z = z1
        if model.complete:
            self.stats["modelled"] += 1
        self.stats["voxels"] += model.size[0] * model.size[1] * (z1 - z0)

    def _shadows(self, model: _Model) -> moderngl.Texture:
        """The smoke's (t_sun, t_sky) texture for ``model``'s inputs, modelled once per change of
        them (a few are kept per effect: keyframes in flight during a fade differ)."""
        u = model.uniforms
        key = (model.size, u["u_extent"], u["u_sun_local"], u["u_sigma"], u["u_opacity"], model.vol.kind, model.vol.profile)
        shadows = model.slot.shadows
        tex = shadows.get(key)
        if tex is not None:
            shadows.move_to_end(key)
            return tex
        tex = self.pool.take(model.size, 2, (moderngl.NEAREST, moderngl.NEAREST))
        program = self.programs.compute("volumes/model.comp.glsl", {"SMOKE": 1, "SHADOWS": 1})
        set_uniforms(program, {**u, "u_z_first": 0})
        use_texture(self._profile_texture(model.vol), 0)
        tex.bind_to_image(0, read=False, write=True)
        program.run(*(math.ceil(n / 4) for n in model.size))
        self.ctx.memory_barrier()
        shadows[key] = tex
        while len(shadows) > MAX_SHADOW_TEXTURES:
            self.pool.give(shadows.popitem(last=False)[1])
        self.stats["shadows"] = self.stats.get("shadows", 0) + 1
        return tex

    # -- rendering ---------------------------------------------------------------------------

    def _vao(self, program):
        if self._cube_vbo is None:
            self._cube_vbo = self.ctx.buffer(_unit_cube_corners().tobytes())
        vao = self._vaos.get(id(program))
        if vao is None:
            vao = self.ctx.vertex_array(program, [(self._cube_vbo, "3f", "in_position")])
            self._vaos[id(program)] = vao
        return vao

    def _low_targets(self, size: tuple[int, int]):
        """Low-resolution colour + distance targets of the reduced-resolution march (one set per
        size: two are in use while the march resolution cross-fades)."""
        held = self._low.get(size)
        if held is None:
            for old in [k for k in self._low if k != self._low_last]:
                for obj in self._low.pop(old):
                    obj.release()
            color = self.ctx.texture(size, 4, dtype="f2")
            distance = self.ctx.texture(size, 1, dtype="f4")
            for tex in (color, distance):
                tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
                tex.repeat_x = tex.repeat_y = False
            color.filter = (moderngl.LINEAR, moderngl.LINEAR)  # the upsample's one filtered fetch
            held = self._low[size] = (color, distance, self.ctx.framebuffer([color]), self.ctx.framebuffer([distance]))
        self._low_last = size
        return held

    def _layers(self, scale: int, sim_time: float) -> list[tuple[int, tuple[float, float]]]:
        """(march scale, dither range) of this frame's layers. When the scale changes in a running
        stream (auto quality moving a rung), the old and the new march dissolve into each other
        over SCALE_FADE_FRAMES frames instead of popping (a pixel shows the new one when its
        dither value is below the weight w, else the old); a re-render or a jump shows the new one."""
        last_scale, last_time = self._scale_state
        self._scale_state = (scale, sim_time)
        dt = sim_time - last_time if last_time is not None else 0.0
        streaming = 0.0 < dt <= MAX_STREAM_DT
        if last_scale is not None and last_scale != scale and streaming:
            self._fade = (last_scale, SCALE_FADE_FRAMES)
        if self._fade is None or not streaming or self._fade[0] == scale:
            self._fade = None
            return [(scale, (0.0, 1.0))]
        old, left = self._fade
        w = 1.0 - left / (SCALE_FADE_FRAMES + 1)
        self._fade = (old, left - 1) if left > 1 else None
        return [(old, (w, 1.0)), (scale, (0.0, w))]

    def execute(self, frame, targets) -> None:
        scene, view = frame.scene, frame.view
        settings = self.knobs(frame)
        self._frame += 1
        self.stats = {"modelled": 0, "drawn": 0, "voxels": 0}
        if frame.resources.get("eye_under_water"):  # the water pass put the eye below the surface: fire and
            return  # smoke are in the air, the water hides them (docs/water.md#under-water)
        # The march's plan (texture sizes, boxes, constants) follows the visible volumes and the knobs.
        key, volumes = self._visible(scene, view)
        plan = self.memo.get("march_plan", (key, settings), lambda: MarchPlan(volumes, scene, view, settings).pack(
            scene, view, settings, self._block_align))
        textures = [self._models_for(plan, i, frame, settings) for i in range(len(volumes))]
        scale = max(max(int(settings.scale), 1), plan.lod_scale)
        self.stats["scale"] = scale
        self._write_block(plan, scene, textures)
        for scale, dither in self._layers(scale, scene.time.sim_time):
            self._draw_layer(frame, targets, plan, textures, settings, scale, dither)
        self._evict()

    def _write_block(self, plan: "MarchPlan", scene: Scene, textures) -> None:
        """The plan's records with this frame's values - the keyframe blend, the start jitter's
        shift, the glow intensities (flicker) - into the block's buffer (one write)."""
        if not textures:
            return
        records = np.frombuffer(plan.records, np.float32).reshape(len(textures), -1).copy()
        records[:, march_block.BLEND] = [blend for _, _, blend in textures]
        records[:, march_block.JITTER] = (scene.host_frame * 0.6180339887) % 1.0  # golden-ratio sequence per frame
        for i, effect, lit in plan.glows:
            light = flame_light(lit, effect, scene.time.sim_time)
            if light is not None:
                records[i, march_block.GLOW:march_block.GLOW + 3] = light.color
        data = records.tobytes()
        if self._block is None or self._block.size < len(data):
            if self._block is not None:
                self._block.release()
            self._block = self.ctx.buffer(reserve=max(len(data), plan.stride) * 2, dynamic=True)
        write_buffer(self._block, data)

    def _draw_layer(self, frame, targets, plan: "MarchPlan", textures, settings: VolumeSettings, scale: int,
                    dither: tuple[float, float]) -> None:
        """March at 1 / ``scale`` resolution and composite into the frame's pixels whose dither
        value is in ``dither`` (a cross-fade layer; [0, 1) otherwise)."""
        distance = frame.resources["scene_distance"]
        if scale > 1:
            width, height = targets.size
            low_size = (-(-width // scale), -(-height // scale))
            low_color, low_distance, color_fbo, distance_fbo = self._low_targets(low_size)
            # Full-resolution work only where the boxes are (the upsample reads one low-res texel
            # around each pixel: the low-resolution rectangle is padded by two).
            x, y, w, h = plan.screen_rect(frame.view, width, height, pad=2 * scale)
            low_rect = (x // scale, y // scale, -(-w // scale) + 2, -(-h // scale) + 2)
            self.ctx.disable(moderngl.DEPTH_TEST | moderngl.BLEND)
            distance_fbo.use()
            distance_fbo.scissor = low_rect
            down = self._program(("down", scale), lambda: self.programs.program(
                "common/fullscreen.vert.glsl", "volumes/downsample.frag.glsl", {"SCALE": scale}))
            set_uniforms(down, {"u_scene_distance": 1})
            use_texture(distance, 1)
            self.fullscreen(down)
            distance_fbo.scissor = None
            color_fbo.use()
            color_fbo.clear(0.0, 0.0, 0.0, 0.0)
            self._march(frame, plan, textures, settings, low_distance, low_size[1], (0.0, 1.0))
            targets.color_fbo.use()  # (blending as the march left it: ONE, ONE_MINUS_SRC_ALPHA)
            targets.color_fbo.scissor = (x, y, w, h)
            fade = tuple(dither) != (0.0, 1.0)
            up = self._program(("up", fade), lambda: self.programs.program(
                "common/fullscreen.vert.glsl", "volumes/upsample.frag.glsl", {"LAYER_FADE": 1} if fade else None))
            set_uniforms(up, {"u_volume_color": 0, "u_volume_distance": 2, "u_scene_distance": 1, "u_scale": scale,
                              "u_volumes_far": plan.far, "u_layer_range": dither})
            use_texture(low_color, 0)
            use_texture(distance, 1)
            use_texture(low_distance, 2)
            self.fullscreen(up)
            targets.color_fbo.scissor = None
            self.ctx.disable(moderngl.BLEND)
        else:
            targets.color_fbo.use()
            self.ctx.disable(moderngl.DEPTH_TEST)
            self._march(frame, plan, textures, settings, distance, targets.size[1], dither)
            self.ctx.disable(moderngl.BLEND)

    def _march(self, frame, plan: "MarchPlan", textures, settings: VolumeSettings, distance, march_height: int,
               dither: tuple[float, float]) -> None:
        """Draw every volume's slabs into the bound framebuffer (premultiplied, far to near) at the
        pixels whose dither value is in ``dither``; ``march_height``: its height in pixels (for
        the footprint of a pixel). A volume is one instanced draw of its slabs, its constants its
        record of the block (march_block.py). Depth testing off before; blending
        (ONE, ONE_MINUS_SRC_ALPHA) left on after."""
        view = frame.view
        self.ctx.enable(moderngl.BLEND | moderngl.CULL_FACE)
        self.ctx.front_face = "ccw"
        self.ctx.cull_face = "front"
        self.ctx.blend_func = moderngl.ONE, moderngl.ONE_MINUS_SRC_ALPHA
        use_texture(distance, 1)
        _, _, bottom, top = view.tangents
        # The frame's aerial-perspective table when the surfaces filled it this frame: one lookup a
        # pixel instead of the atmosphere per pixel (a tenth of the close fire's march); else per pixel.
        table = frame.resources.get("aerial_table")
        aerial = None
        if table is not None:
            table.bind()
            aerial = table.uniforms()
        self.stats["aerial_table"] = aerial is not None
        per_frame = {
            "u_volume": 0, "u_volume_next": 2, "u_scene_distance": 1,
            "u_pixel_angle": (math.atan(top) - math.atan(bottom)) / max(march_height, 1),  # rad per march pixel
            "u_layer_range": dither,
        }
        programs = {}
        for i, (tex, tex_next, _) in enumerate(textures):
            smoke = plan.smoke[i]
            program = programs.get(smoke)
            if program is None:
                variant = (smoke, aerial is None, settings.model_hz > 0.0, tuple(dither) != (0.0, 1.0))
                program = programs[smoke] = self._program(("march", *variant), lambda: self._march_program(*variant))
                set_uniforms(program, frame.uniforms)
                set_uniforms(program, {**aerial, **per_frame} if aerial else per_frame)
            self._block.bind_to_uniform_block(BLOCKS["VOLUME"], offset=i * plan.stride, size=march_block.RECORD_BYTES)
            use_texture(tex, 0)
            use_texture(tex_next, 2)
            # The container as slabs (Volume.slabs), each marching its own stretch of the ray, drawn
            # farthest first (MarchPlan): the ONE, ONE_MINUS_SRC_ALPHA blend composes them as one
            # front-to-back march would.
            self._vao(program).render(moderngl.TRIANGLES, instances=plan.slab_counts[i])
            self.stats["drawn"] += 1
        self.stats["slabs"] = self.stats.get("slabs", 0) + sum(plan.slab_counts)
        self.ctx.disable(moderngl.CULL_FACE)
        self.ctx.cull_face = "back"

    def _march_program(self, smoke: bool, exact: bool, blend: bool, fade: bool):
        defines = {"SMOKE": 1} if smoke else {}
        if exact:
            defines["AERIAL_EXACT"] = 1
        if blend:
            defines["BLEND"] = 1
        if fade:
            defines["LAYER_FADE"] = 1  # a cross-fade layer: the per-pixel dither and discard
        return self.programs.program("volumes/march.vert.glsl", "volumes/march.frag.glsl", defines or None)

    def _program(self, variant: tuple, make):
        """The pass's program of ``variant`` (a few flags), from the program cache once."""
        program = self._programs.get(variant)
        if program is None:
            program = self._programs[variant] = make()
        return program

    def _evict(self) -> None:
        """Free the textures of effects not seen for a while (gone, out of view, inactive)."""
        for key in [k for k, s in self._slots.items() if self._frame - s.last_frame > EVICT_AFTER_FRAMES]:
            self._slots[key].release()
            del self._slots[key]


__all__ = ["VolumesPass", "VolumeSettings", "PRESETS", "volumes_needed", "texture_size", "model_octaves",
           "footprint_scale"]
