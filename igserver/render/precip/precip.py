"""Precipitation pass: rain and snow streaks (docs/design.md#precipitation).

Absent from the frame graph when nothing falls (``weather.precipitation.type == "none"`` or rate 0).
Otherwise, per frame: the CPU moves the particles of one wrapped cube in float64 (particles.py:
the visible tiles, the levels and the particles' constants are a layout made once per change of
the view's orientation, the weather or the knobs, uploaded with it); a compute pass lights every
streak once - sun, moon, sky and the point/spot lights, then the aerial perspective
(precip_light.comp.glsl); the GPU draws every particle of every tile as a streak quad
(precip.vert.glsl: one indirect command per level, one instance per tile) clipped by the copied
scene distance (precip.frag.glsl).

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
from .particles import MAX_LEVELS, ParticleLayout, ParticlePool, particle_layout

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
        self._vao_tiles = None  # the tiles buffer the vertex array reads
        self._layout = None  # the particle layout whose tiles, level table and commands are uploaded
        self._level_table: dict = {}

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
        data = np.ascontiguousarray(data, dtype=np.float32)
        buf = self._buffer(name, data.nbytes)
        buf.write(data)
        return buf

    def execute(self, frame, targets) -> None:
        scene, view = frame.scene, frame.view
        if frame.resources.get("eye_under_water"):  # the water pass put the eye below the surface: no rain
            self.stats = {"particles": 0, "tiles": 0, "streaks": 0, "drops_per_streak": 0}
            return
        settings = self.knobs(frame)
        layout = particle_layout(scene, view, settings, self.pool)
        levels = layout.levels
        streaks = sum(level.streaks for level in levels)
        self.stats = {"particles": levels[0].particles if levels else 0, "tiles": len(layout.tiles),
                      "streaks": streaks, "drops_per_streak": levels[0].drops_per_streak if levels else 0.0}
        if streaks == 0:
            return
        self._draw(frame, targets, layout, streaks)

    def _draw(self, frame, targets, layout: ParticleLayout, streaks: int) -> None:
        kind = frame.scene.weather.precipitation.type
        view = frame.view
        rows = layout.pack(frame.scene.time.sim_time, view.position)
        self._upload("particles", rows).bind_to_storage_buffer(0)
        if self._layout is not layout:  # the tiles, the level table and the draw commands: once per layout
            self._set_layout(layout)
        self._buffers["tiles"].bind_to_storage_buffer(1)
        self._buffer("radiance", streaks * 16).bind_to_storage_buffer(2)  # vec4 per streak

        # Every streak of every level in one dispatch (the level found from the table). Run every
        # frame: it reads the frame's block like the draw programs.
        light = self.programs.compute("precip/precip_light.comp.glsl", {**local_light_defines(frame.lights),
                                                                        "FRAME_BLOCK": 1})
        set_uniforms(light, frame.uniforms)
        set_uniforms(light, {**OPTICS[kind], **self._level_table, "u_streaks": streaks})
        light.run((streaks + 63) // 64)
        self.ctx.memory_barrier()

        program = self.programs.program("precip/precip.vert.glsl", "precip/precip.frag.glsl")
        set_uniforms(program, frame.uniforms)
        set_uniforms(program, {
            **self._level_table,
            "u_scene_distance": 0,
            "u_fade": float(layout.fade),
            "u_px_per_tan": float(0.5 * view.height * view.projection[1, 1]),
        })
        use_texture(frame.resources["scene_distance"], 0)
        vao = self._vertex_array(program, max(level.particles for level in layout.levels))
        targets.color_fbo.use()
        self.ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        self.ctx.enable(moderngl.BLEND)
        self.ctx.blend_func = moderngl.ONE, moderngl.ONE_MINUS_SRC_ALPHA
        # One indirect command per level (its tiles as instances, from its first tile on), in order.
        vao.render_indirect(self._buffers["commands"], moderngl.TRIANGLES, count=len(layout.levels))
        self.ctx.disable(moderngl.BLEND)

    def _set_layout(self, layout: ParticleLayout) -> None:
        """Upload what a particle layout fixes: its tiles (with their level), the level table
        (uniforms) and the indirect draw commands."""
        levels = layout.levels
        tiles = np.zeros((len(layout.tiles), 4), np.float32)
        tiles[:, :3] = layout.tiles
        table = np.zeros((MAX_LEVELS, 4), np.int32)
        drops = np.zeros(MAX_LEVELS, np.float32)
        # DrawElementsIndirectCommand: count, instanceCount, firstIndex, baseVertex, baseInstance
        commands = np.zeros((len(levels), 5), np.uint32)
        first_streak = 0
        for i, level in enumerate(levels):
            tiles[level.first_tile:level.first_tile + level.tile_count, 3] = i
            table[i] = (level.first_tile, level.first_particle, level.particles, first_streak)
            drops[i] = level.drops_per_streak
            commands[i] = (6 * level.particles, level.tile_count, 0, 0, level.first_tile)
            first_streak += level.streaks
        self._buffer("tiles", tiles.nbytes).write(tiles.tobytes())  # (a new buffer: _vertex_array remakes its array)
        self._buffer("commands", commands.nbytes).write(commands.tobytes())
        self._level_table = {"u_levels": table.tobytes(), "u_level_drops": drops.tobytes(),
                             "u_level_count": len(levels)}
        self._layout = layout

    def _vertex_array(self, program, quads: int):
        """A vertex array of ``program`` with the tiles as a per-instance attribute and an index
        buffer of quads (0 1 2, 0 2 3) + 4 i, grown in powers of two (a vertex array draws with the
        program and buffers it was made for: remade when one changes)."""
        tiles = self._buffers["tiles"]
        if self._vao is not None and self._quads >= quads and self._vao_program is program and self._vao_tiles is tiles:
            return self._vao
        if self._vao is not None:
            self._vao.release()
        if self._quads < quads:
            self._quads = 1 << max(quads - 1, 0).bit_length()
            base = (np.arange(self._quads, dtype=np.uint32) * 4)[:, None]
            indices = (base + np.array([0, 1, 2, 0, 2, 3], dtype=np.uint32)).ravel()
            if self._index_buffer is not None:
                self._index_buffer.release()
            self._index_buffer = self.ctx.buffer(indices.tobytes())
        self._vao = self.ctx.vertex_array(program, [(tiles, "4f/i", "in_tile")], index_buffer=self._index_buffer,
                                          index_element_size=4)
        self._vao_program, self._vao_tiles = program, tiles
        return self._vao


__all__ = ["PrecipPass", "OPTICS"]
