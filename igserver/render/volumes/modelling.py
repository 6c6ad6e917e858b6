"""The volumes pass's modelling stage: every visible volume's 3D texture (rgba16f, colour + density),
written by a compute shader (model.comp.glsl) from the effect's revolved profile and the turbulence, the
smoke's shadow textures and the profile textures it reads; an effect keeps one texture or its keyframes
(_Slot), freed when the effect has not been seen for a while. VolumeModelling is this half of
VolumesPass (volumes.py); the march is the other.

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
"""

from __future__ import annotations

import math
from collections import OrderedDict

import moderngl

from ..bindings import use_texture
from ...assets import AssetError, resolve_asset
from ...effect_kinds import EFFECT_KINDS
from ..texture_pool import TexturePool
from ..shaders import set_uniforms
from .effects import NOISE_PERIOD, NOISE_SCALE, Volume
from .march import MarchPlan, extinction, scattering
from .profiles import load_profile
from .settings import VolumeSettings

MAX_SHADOW_TEXTURES = 3  # per smoke effect: the keyframes in flight (k, k + 1, k + 2) may differ in a fade
MAX_PROFILE_TEXTURES = 32  # profile textures kept resident (LRU); each is small, their number is not
PUFF_AMPLITUDE = 0.25  # a puffing flame's necks and bulges: its radius x (1 +- 0.25)
EVICT_AFTER_FRAMES = 120


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


class VolumeModelling:
    """The modelling stage of VolumesPass: each effect's slot of modelled textures (``_slots``), the
    profile textures (``_profiles``) and the smoke's shadows, in 3D textures from ``pool``. It uses
    the pass's ``ctx``, ``programs``, ``_program``, ``_frame`` (the frame count a slot was last used
    at) and counts into its ``stats``."""

    def __init__(self, ctx, programs):
        super().__init__(ctx, programs)
        self.pool = TexturePool(ctx)  # keyframes' and smoke shadows' 3D textures, reused
        self._slots: dict[tuple, _Slot] = {}
        self._profiles: OrderedDict[tuple, moderngl.Texture] = OrderedDict()  # LRU, at most MAX_PROFILE_TEXTURES
        self._model_inputs: dict = {}  # modelling program -> the model inputs (dict) last written to it

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

    def _evict(self) -> None:
        """Free the textures of effects not seen for a while (gone, out of view, inactive)."""
        for key in [k for k, s in self._slots.items() if self._frame - s.last_frame > EVICT_AFTER_FRAMES]:
            self._slots[key].release()
            del self._slots[key]


__all__ = ["VolumeModelling", "model_octaves"]
