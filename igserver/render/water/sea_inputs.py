"""What the water programs read besides the frame's uniforms: the wave set's table and phases, a
bathymetry's field textures, the foam's tabulated noise and the eye's motion for the detail maps'
blur (a mixin of the water pass: it holds the resources on the pass's context)."""

from __future__ import annotations

import moderngl
import numpy as np

from ...scene.model import Scene
from ...water.surface import SeaSurface
from ..bindings import PASS_UNITS, use_texture
from ..camera import CameraView
from ..post.exposure import MAX_STREAM_DT
from ..shaders import set_uniforms
from . import lod
from .foam import FOAM_NOISE_SIZE, FOAM_PERIOD, rows_channel_cells

MAX_WAVES = 64
FIELD_UNIT = PASS_UNITS["SEA_FIELD"]
FIELD_SCALAR_UNIT = PASS_UNITS["SEA_FIELD_SCALAR"]


class SeaInputs:
    """Needs ``ctx``, ``programs``, ``fullscreen`` (RenderPass) and the attributes ``_field_key``,
    ``_field_tex``, ``_foam_noise_tex``, ``_last_eye`` set by the pass."""

    def _upload_field(self, sea: SeaSurface) -> None:
        if self._field_key is sea:
            return
        if self._field_tex is not None:
            for tex in self._field_tex:
                tex.release()
            self._field_tex = None
        self._field_key = sea
        f = sea.field
        if f is None:
            return
        n, nu, nv = f.residual.shape
        data = np.stack([f.residual, f.factor, f.kvec[..., 0], f.kvec[..., 1]], axis=-1)  # (n, nu, nv, 4)
        data = np.ascontiguousarray(np.transpose(data, (0, 2, 1, 3)), dtype=np.float32)  # rows = v
        field = self.ctx.texture_array((nu, nv, n), 4, data.tobytes(), dtype="f4")
        scalar = np.stack([f.steepness, f.depth, f.breaking, np.zeros_like(f.depth)], axis=-1)
        scalar = np.ascontiguousarray(scalar.transpose(1, 0, 2), dtype=np.float32)
        scalar_tex = self.ctx.texture((nu, nv), 4, scalar.tobytes(), dtype="f4")
        for tex in (field, scalar_tex):  # bilinear between nodes, edges clamped (gerstner.glsl)
            tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
            tex.repeat_x = tex.repeat_y = False
        self._field_tex = (field, scalar_tex)

    def _foam_noise(self) -> moderngl.Texture:
        """The foam's streak noise (water/foam_noise.frag.glsl), tabulated once per context."""
        if self._foam_noise_tex is None:
            tex = self.ctx.texture((FOAM_NOISE_SIZE, FOAM_NOISE_SIZE), 4, dtype="f1")
            fbo = self.ctx.framebuffer(color_attachments=[tex])
            program = self.programs.program("common/fullscreen.vert.glsl", "water/foam_noise.frag.glsl")
            cells_g, cells_b = rows_channel_cells()
            set_uniforms(program, {"u_period": FOAM_PERIOD, "u_cells_g": cells_g, "u_cells_b": cells_b})
            fbo.use()
            self.ctx.disable(moderngl.DEPTH_TEST | moderngl.BLEND)
            self.fullscreen(program)
            fbo.release()
            tex.repeat_x = tex.repeat_y = True
            tex.filter = (moderngl.LINEAR, moderngl.LINEAR)  # no mipmaps: a trilinear fetch costs 2x
            self._foam_noise_tex = tex
        return self._foam_noise_tex

    def wave_uniforms(self, sea: SeaSurface, scene: Scene, view: CameraView) -> dict:
        t = scene.time.sim_time
        cam_xy = view.position[:2]
        w = sea.waves
        table = np.zeros((MAX_WAVES, 4), dtype=np.float32)
        n = min(w.n, MAX_WAVES)
        table[:n, 0:2] = (w.k[:, None] * w.direction)[:n]
        table[:n, 2] = w.amplitude[:n]
        table[:n, 3] = w.omega[:n]
        phases = np.zeros(MAX_WAVES, dtype=np.float32)
        phases[:n] = sea.phase_offsets(t, cam_xy)[:n]
        u = {"u_wave_count": n, "u_wave_norm": float(max(n, 1)), "u_steepness": sea.steepness,
             "u_second_order": sea.second_order, "u_sea_depth": sea.reference_depth,
             "u_cam_height": float(view.position[2] - scene.ocean.level),
             "u_level_z": float(scene.ocean.level - view.position[2]),
             "u_patch_quads": float(lod.PATCH_QUADS)}
        if sea.field is not None:
            g = sea.field.grid
            u.update({"u_field_origin": tuple(float(x) for x in g.origin - cam_xy),
                      "u_field_u": tuple(float(x) for x in g.u), "u_field_v": tuple(float(x) for x in g.v),
                      "u_field_cell": (float(g.du), float(g.dv)), "u_field_size": (g.nu, g.nv),
                      "u_field": FIELD_UNIT, "u_field_scalar": FIELD_SCALAR_UNIT})
        return {"uniforms": u, "table": table.tobytes(), "phases": phases.tobytes()}

    def _wave_values(self, sea, wu: dict) -> dict:
        """The wave set's uniform values (``wave_uniforms``), with a bathymetry's field textures bound."""
        if sea.field is not None:
            self._upload_field(sea)
            use_texture(self._field_tex[0], FIELD_UNIT)
            use_texture(self._field_tex[1], FIELD_SCALAR_UNIT)
        return {**wu["uniforms"], "u_wave": wu["table"], "u_wave_phase": wu["phases"]}

    def detail_motion(self, scene, view) -> tuple[float, float]:
        """The detail ripples' apparent displacement across this frame (m, world x, y): the eye's
        horizontal motion since the previous frame of this view when that frame was the last of one
        stream (0 < dt <= MAX_STREAM_DT); (0, 0) for a still eye, a first frame or a jump. The detail
        maps are blurred over it (water.frag.glsl detail: a full-interval shutter), so a ripple the eye
        passes by more than half its length a frame does not alias into shimmer."""
        t, eye = float(scene.time.sim_time), np.array(view.position[:2], dtype=np.float64)
        last, self._last_eye = self._last_eye, (t, eye)
        if last is None or not 0.0 < t - last[0] <= MAX_STREAM_DT:
            return 0.0, 0.0
        moved = eye - last[1]
        return float(moved[0]), float(moved[1])
