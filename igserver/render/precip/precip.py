"""Precipitation pass: rain and snow streaks (docs/design.md#precipitation).

Absent from the frame graph when nothing falls (``weather.precipitation.type == "none"`` or rate 0).
Otherwise, per frame: the CPU moves the particles of one wrapped cube in float64 and lists the
visible tiles (particles.py); a compute pass lights every streak once - sun, moon, sky and the
point/spot lights, then the aerial perspective (precip_light.comp.glsl); the GPU draws every
particle of every tile as a streak quad (precip.vert.glsl, instanced: one instance per tile)
clipped by the copied scene distance (precip.frag.glsl).

Cost is bounded: at most ``max_streaks`` quads whatever the rate (particles.py), and the CPU work is
O(particles per tile) numpy.
"""

from __future__ import annotations

import moderngl
import numpy as np

from ...scene.model import Scene
from ...weather import precipitation_falls
from ..bindings import use_texture
from ..camera import CameraView
from ..frame import local_light_defines
from ..passes import RenderPass
from ..shaders import set_uniforms
from .particles import ParticleFrame, ParticlePool, particle_frame

# Per-type optics: a raindrop shows the sky around it and scatters light forward (refraction);
# a snowflake is a rough white scatterer, nearly isotropic with a little backscatter.
OPTICS = {"rain": {"u_albedo": 1.0, "u_phase_g": 0.6}, "snow": {"u_albedo": 0.9, "u_phase_g": -0.1}}


class PrecipPass(RenderPass):
    name = "precip"
    reads_scene_distance = True
    preset_pipeline = "precip"

    def __init__(self, ctx, programs):
        super().__init__(ctx, programs)
        self.pool = ParticlePool()
        self.stats = {"particles": 0, "tiles": 0, "streaks": 0, "drops_per_streak": 0.0}
        self._buffers: dict[str, moderngl.Buffer] = {}
        self._vao = None
        self._vao_program = None
        self._index_buffer = None
        self._quads = 0  # quads the index buffer holds

    def needed(self, scene: Scene, view: CameraView) -> bool:
        return precipitation_falls(scene)

    def _buffer(self, name: str, nbytes: int) -> moderngl.Buffer:
        """A storage buffer of at least ``nbytes``, kept between frames (grown by doubling)."""
        buf = self._buffers.get(name)
        if buf is None or buf.size < nbytes:
            if buf is not None:
                buf.release()
            buf = self.ctx.buffer(reserve=max(nbytes, 16) * 2)
            self._buffers[name] = buf
        return buf

    def _upload(self, name: str, data: np.ndarray) -> moderngl.Buffer:
        raw = np.ascontiguousarray(data, dtype=np.float32).tobytes()
        buf = self._buffer(name, len(raw))
        buf.write(raw)
        return buf

    def execute(self, frame, targets) -> None:
        scene, view = frame.scene, frame.view
        if frame.resources.get("eye_under_water"):  # the water pass put the eye below the surface: no rain
            self.stats = {"particles": 0, "tiles": 0, "streaks": 0, "drops_per_streak": 0}
            return
        settings = self.knobs(frame)
        particles = particle_frame(scene, view, settings, self.pool)
        near = particles.levels[0].particles if particles.levels else 0
        self.stats = {"particles": near, "tiles": len(particles.tiles),
                      "streaks": particles.streak_count, "drops_per_streak": particles.drops_per_streak}
        if particles.streak_count == 0:
            return
        self._draw(frame, targets, particles)

    def _draw(self, frame, targets, particles: ParticleFrame) -> None:
        kind = frame.scene.weather.precipitation.type
        n = len(particles.positions)
        packed = np.empty((n, 8), dtype=np.float64)
        packed[:, 0:3] = particles.positions
        packed[:, 3] = particles.diameters
        packed[:, 4:7] = particles.streaks
        packed[:, 7] = particles.brightness
        tiles = np.zeros((len(particles.tiles), 4))
        tiles[:, :3] = particles.tiles
        self._upload("particles", packed).bind_to_storage_buffer(0)
        self._upload("tiles", tiles).bind_to_storage_buffer(1)

        self._buffer("radiance", particles.streak_count * 16).bind_to_storage_buffer(2)  # vec4 per streak
        view = frame.view
        # Per level: its entries in radiance[] (one per streak) start at first_streak.
        first_streak = np.cumsum([0] + [level.streaks for level in particles.levels])[:-1]

        # Run every frame: it reads the frame's block like the draw programs.
        light = self.programs.compute("precip/precip_light.comp.glsl", {**local_light_defines(frame.lights),
                                                                        "FRAME_BLOCK": 1})
        set_uniforms(light, frame.uniforms)
        set_uniforms(light, OPTICS[kind])
        for level, base in zip(particles.levels, first_streak):
            set_uniforms(light, {**self._level_uniforms(level, int(base)), "u_streaks": level.streaks})
            light.run((level.streaks + 63) // 64)
        self.ctx.memory_barrier()

        program = self.programs.program("precip/precip.vert.glsl", "precip/precip.frag.glsl")
        set_uniforms(program, frame.uniforms)
        set_uniforms(program, {
            "u_scene_distance": 0,
            "u_fade": float(particles.fade),
            "u_px_per_tan": float(0.5 * view.height * view.projection[1, 1]),
        })
        use_texture(frame.resources["scene_distance"], 0)
        self._quad_indices(program, max(level.particles for level in particles.levels))
        targets.color_fbo.use()
        self.ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        self.ctx.enable(moderngl.BLEND)
        self.ctx.blend_func = moderngl.ONE, moderngl.ONE_MINUS_SRC_ALPHA
        for level, base in zip(particles.levels, first_streak):  # one instanced draw per level
            set_uniforms(program, {**self._level_uniforms(level, int(base)),
                                   "u_drops_per_streak": float(level.drops_per_streak)})
            self._vao.render(moderngl.TRIANGLES, vertices=6 * level.particles, instances=level.tile_count)
        self.ctx.disable(moderngl.BLEND)

    @staticmethod
    def _level_uniforms(level, first_streak: int) -> dict:
        return {"u_first_tile": level.first_tile, "u_first_particle": level.first_particle,
                "u_particles": level.particles, "u_first_streak": first_streak}

    def _quad_indices(self, program, quads: int) -> None:
        """Index buffer of quads (0 1 2, 0 2 3) + 4 i, grown in powers of two, in a vertex array of
        ``program`` (a vertex array draws with the program it was made for: remade when it changes)."""
        if self._vao is not None and self._quads >= quads and self._vao_program is program:
            return
        if self._vao is not None:
            self._vao.release()
        if self._quads < quads:
            self._quads = 1 << max(quads - 1, 0).bit_length()
            base = (np.arange(self._quads, dtype=np.uint32) * 4)[:, None]
            indices = (base + np.array([0, 1, 2, 0, 2, 3], dtype=np.uint32)).ravel()
            if self._index_buffer is not None:
                self._index_buffer.release()
            self._index_buffer = self.ctx.buffer(indices.tobytes())
        self._vao = self.ctx.vertex_array(program, [], index_buffer=self._index_buffer, index_element_size=4)
        self._vao_program = program


__all__ = ["PrecipPass", "OPTICS"]
