"""Water pass (docs/design.md#water): the wind-driven Gerstner sea on a CDLOD mesh, shaded with the sky.

CPU side per frame: the wave set and its bathymetry field come from igserver.water (cached per
state: integrated once per bathymetry + wave set); phases are reduced in float64 (sim_time 1e9 s is
as good as 100 s); the LOD selection picks the blocks (lod.py); the detail normal maps are rendered
for the frame's time (three tiles, summed in the water shader).

The pass's parts: the detail maps and what each block reads of them (detail.py, detail_synth.py), the
foam (foam.py), the hulls that keep the sea out (hulls.py), the sky reflection and aerial perspective
tables (sea_tables.py), the shore (shore.py), the program variant and draw group of each block
(draw_plan.py), the waves', the field's and the foam noise's inputs (sea_inputs.py), the view from
under the surface (underwater.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import moderngl
import numpy as np

from ...scene.model import Scene
from ...water import sea_surface
from ...water.surface import SeaSurface
from ..bindings import PASS_UNITS, use_texture, write_buffer
from ..memo import Memo
from ..camera import CameraView
from ..frame import local_light_defines
from .. import presets
from ..passes import RenderPass
from ..shaders import assemble, set_uniforms
from . import lod
from .detail import DETAIL_MAPS, detail_fixed_tiles, detail_means_at, detail_synth_tables, detail_unresolved_var
from .detail_synth import DetailSynthGL
from .draw_plan import PlanSwitches, draw_plan
from .foam import FOAM_EDGE, FOAM_NOISE_UNIT, dots_defines, foam_calibration, foam_drawn, foam_frame, streak_variant
from .hulls import MAX_HULLS, hull_boxes
from .sea_inputs import MAX_WAVES, SeaInputs
from .shore import shore_uniforms
from .sea_tables import SeaTables
from .underwater import UnderwaterDraws, underwater_uniforms

# Texture units bound for the water draw (the frame keeps 8..15: haze table, sky-view table, 4D tables).
DETAIL_UNIT0 = PASS_UNITS["SEA_DETAIL0"]  # and the next two


@dataclass(frozen=True)
class WaterKnobs:
    """Per quality level, relative to the scene's own ``ocean`` settings (medium = exactly those, so a
    scene or the quality study that sets them gets what it set). The wave count is NOT a knob: it
    defines the sea itself, which the host's height queries (hulls placed on it) must describe
    whatever the picture quality."""

    detail_scale: float  # × ocean.detail_resolution (texels per side of each detail map)
    lod_error_scale: float  # × ocean.lod_error (px)
    mesh: str = "default"  # the LOD ring rule (lod.MESHES): "coarse" draws 2.25× fewer vertices


# From `igserver quality water`: the detail-map resolution costs its re-rendering each frame and moves
# the picture by < 0.2 levels between 64² and 256²; the LOD error bound does not bind at 640x360
# (the crack-free range rule decides the mesh there), it does on large frames and high seas.
PRESETS = {
    "low": WaterKnobs(detail_scale=0.5, lod_error_scale=2.0, mesh="coarse"),
    "medium": WaterKnobs(detail_scale=1.0, lod_error_scale=1.0),
    "high": WaterKnobs(detail_scale=2.0, lod_error_scale=0.5),
}
presets.register("water", PRESETS)






def glint_light(uniforms: dict) -> dict:
    """The sun or the moon, whichever gives more light: the one glitter the water shader draws."""
    sun, moon = np.asarray(uniforms["u_sun_illuminance"]), np.asarray(uniforms["u_moon_illuminance"])
    use_sun = float(np.sum(sun)) >= float(np.sum(moon))
    return {"u_glint_dir": tuple(uniforms["u_sun_dir" if use_sun else "u_moon_dir"]),
            "u_glint_illuminance": tuple(float(x) for x in (sun if use_sun else moon))}


class WaterPass(UnderwaterDraws, SeaInputs, RenderPass):
    name = "water"
    preset_pipeline = "water"
    # the LOD selection (select); the eye's last frame (detail_motion); the blocks' instance buffers and
    # their vertex arrays (_vao)
    view_state = ("_selection", "_last_eye", "_instances", "_block_vaos")
    view_counters = ("_selection_version",)
    _selection = None
    _last_eye = None

    def __init__(self, ctx, programs):
        super().__init__(ctx, programs)
        self._patch = None
        self._field_key = None
        self._field_tex = None
        self._detail = None
        self._detail_key = None  # (tables, t, maps) the detail maps hold
        self._detail_synth = DetailSynthGL(ctx, programs)
        self._tables: SeaTables | None = None
        self._selection = None  # (key, sea, LodSelection) of the last select()
        self._selection_version = 0  # counts select()'s recomputations: a key part for what follows it
        self.memo = Memo()
        self.exact_atmosphere = False  # the atmosphere per pixel/vertex instead of the tables (quality study)
        self.skip_minified_maps = True  # False: every block reads every detail map (tests' reference)
        self.skip_faded_streaks = True  # False: every block reads the foam's streak noise (tests' reference)
        self.skip_offshore_land = True  # False: every block over a field draws the swash and the land (tests' reference)
        self.coarse_flat_sides = True  # False: every fan keeps its G segments a side (tests' reference)
        self.foam_threshold: float | None = None  # tests: a J threshold instead of the calibrated one
        self.detail_fade = True  # False: the detail maps' slopes unfaded by the footprint (tests' reference)
        self.caustics = True  # False: the bed under water evenly lit (tests' reference)
        self._foam_noise_tex: moderngl.Texture | None = None
        self.stats: dict = {}
        self._underwater: dict | None = None  # this frame's under-water uniforms when the eye is below the surface

    def needed(self, scene: Scene, view: CameraView) -> bool:
        return scene.ocean.enabled

    # ---- resources ------------------------------------------------------------------------------
    def _program(self, field: bool, hulls: bool = False, detail_maps: int = DETAIL_MAPS,
                 lights: dict | None = None, foam_streaks: int = 2, values: dict | None = None,
                 land: bool = True, foam: bool = True) -> moderngl.Program:
        """``lights``: frame.local_light_defines (None: every light term compiled); ``values``: the
        frame's uniform values (``_frame_uniforms``), which pick the variants of what is off this frame
        (None: everything compiled in, no motion); ``land``: over a field, whether the swash and the
        land are drawn (shore.py blocks_reaching_land); ``foam``: whether the sea draws foam (foam.py
        foam_drawn)."""
        defines = {"MAX_WAVES": MAX_WAVES, "MAX_HULLS": MAX_HULLS, "WATER_DETAIL_MAPS": detail_maps, "WATER_FOAM": int(foam),
                   **(lights or {}), "WATER_FOAM_STREAKS": int(foam_streaks), **self._atmosphere_define()}
        if field:
            defines["WATER_FIELD"] = 1
            defines["WATER_LAND"] = int(land)
        if hulls:
            defines["WATER_HULLS"] = 1
        if self._underwater is not None:  # the eye below the surface (water/underwater.glsl)
            defines["WATER_UNDERWATER"] = 1
        defines["WATER_DETAIL_FADE"] = int(self.detail_fade)
        # Variants instead of branches on uniforms (llvmpipe runs both sides of a branch): the detail
        # maps' motion blur for a moving eye, the fog top's relief for a fog top below the eye.
        values = values or {}
        defines["WATER_DETAIL_MOTION"] = int(tuple(values.get("u_detail_motion", (0.0, 0.0))) != (0.0, 0.0))
        defines["FOG_RELIEF"] = int(values.get("u_fog_relief", (0.0, 0.0, 1.0, 0.0))[2] > 0.0)
        if foam:
            defines.update(dots_defines(values))
        else:  # the streaks and the dots are the foam's: without it every choice of them is one program
            defines.update({"WATER_FOAM_STREAKS": 0, "WATER_FOAM_DOTS": 0})
        return self.programs.program("water/water.vert.glsl", "water/water.frag.glsl", defines)

    def _atmosphere_define(self) -> dict:
        return {"WATER_EXACT_ATMOSPHERE": 1} if self.exact_atmosphere else {}

    def capture_program(self, field: bool) -> moderngl.Program:
        """The water vertex shader alone, capturing v_rel by transform feedback (tests, quality)."""
        key = ("water-capture", field)
        cache = self.programs._programs
        if key not in cache:
            defines = {"MAX_WAVES": MAX_WAVES, "MAX_HULLS": MAX_HULLS, **({"WATER_FIELD": 1} if field else {})}
            cache[key] = self.ctx.program(vertex_shader=assemble("water/water.vert.glsl", "VERTEX", defines),
                                          varyings=["v_rel"])
        return cache[key]

    def _patch_buffer(self, fan: int = -1) -> tuple[moderngl.Buffer, moderngl.Buffer]:
        """The patch's (G+1)² grid vertices and an index buffer: the full G×G patch (``fan`` -1), or
        the fan of a flat block whose sides in the mask ``fan`` are one segment (lod.fan_indices: the
        same border vertices as the full patch on every other side)."""
        if self._patch is None:
            g = lod.PATCH_QUADS
            i, j = np.meshgrid(np.arange(g + 1), np.arange(g + 1), indexing="ij")
            verts = np.column_stack([i.ravel(), j.ravel()]).astype(np.float32)
            self._patch = (self.ctx.buffer(verts.tobytes()), {-1: self.ctx.buffer(lod.patch_indices().tobytes())})
        verts, indices = self._patch
        if fan not in indices:
            indices[fan] = self.ctx.buffer(lod.fan_indices(fan).tobytes())
        return verts, indices[fan]

    def _update_detail(self, sea: SeaSurface, t: float, resolution: int, tiles, read: int) -> None:
        """Write the first ``read`` detail maps of ``tiles`` (those some block reads; the others are
        empty or fully minified everywhere this frame) for time ``t``, with their mip chains: compute
        passes from tables made once per sea state and resolution (detail_synth.py), dispatched here
        and copied into the textures before the draws (``execute``)."""
        if self._detail is None or self._detail[0].size[0] != resolution:
            if self._detail is not None:
                for tex in self._detail:
                    tex.release()
            self._detail_key = None
            self._detail = [self.ctx.texture((resolution, resolution), 4, dtype="f4") for _ in range(DETAIL_MAPS)]
            for tex in self._detail:
                tex.build_mipmaps()  # allocates the chain that the synthesis writes level by level
                tex.repeat_x = tex.repeat_y = True
                # Bilinear in the nearest level, not trilinear: half the texels a read (the water pass's
                # CPU -6 % on llvmpipe). Each band-limited level keeps the slope variance it no longer
                # resolves in its second moments, and the footprint fade has softened a map's slopes
                # before its level changes, so the switch does not show (shimmer of a moving eye at
                # 2-20 m/s 0.21/0.04/0.00/0.35 % of the near pixels, 0.19/0.03/0.00/0.35 trilinear).
                tex.filter = (moderngl.LINEAR_MIPMAP_NEAREST, moderngl.LINEAR)
        if not any(len(waves) for _, waves in tiles[:read]):
            return
        # The maps depend on the sea state and the time only: a frame at the same time (another view,
        # a re-render of a paused scene) reuses them. (The tables are cached per sea state and
        # resolution, so their identity is the state.)
        tables = detail_synth_tables(sea, resolution)
        held = self._detail_key
        if held is not None and held[0] is tables and held[1] == float(t) and held[2] >= read:
            return
        # On a GPU the passes run while the frame's uniforms and programs are made here; the copies
        # into the textures come just before the first draw (execute).
        self._detail_synth.dispatch(tables, float(t), read)
        self._detail_key = (tables, float(t), read)

    def select(self, sea: SeaSurface, scene: Scene, view: CameraView, lod_error_scale: float = 1.0,
               mesh: str = "default") -> lod.LodSelection:
        cam = scene.camera
        fov = cam.fov_y if cam.frustum is None else cam.frustum.top - cam.frustum.bottom
        # The selection depends on the view, the sea (its wave set and field: one object per state,
        # igserver.water's cache) and the knobs, not on the time: a still camera selects once.
        key = (view.position.tobytes(), view.view_proj.tobytes(), int(view.height), view.far, id(sea),
               scene.ocean.level, fov, scene.ocean.lod_error * lod_error_scale, mesh, lod.PATCH_QUADS,
               lod.SPACING_PER_WAVE, self.coarse_flat_sides)
        if self._selection is not None and self._selection[0] == key and self._selection[1] is sea:
            return self._selection[2]
        selection = lod.select(view, float(view.position[2] - scene.ocean.level), sea.waves.k, sea.waves.amplitude
                               * (np.max(sea.field.factor, axis=(1, 2)) if sea.field is not None else 1.0),
                               fov, min(scene.ocean.lod_error * lod_error_scale, 16.0), view.far, mesh,
                               fans=sea.field is None,  # a field's depth and surf vary per vertex even where flat
                               coarse_sides=self.coarse_flat_sides)
        self._selection = (key, sea, selection)
        self._selection_version += 1
        return selection

    def execute(self, frame, targets) -> None:
        scene, view = frame.scene, frame.view
        sea = sea_surface(scene.ocean, scene.weather)
        t = scene.time.sim_time
        knobs = self.knobs(frame)
        # A power of two (each mip level halves it exactly): the nearest to the scene's × the preset's scale.
        resolution = 2 ** min(max(round(math.log2(scene.ocean.detail_resolution * knobs.detail_scale)), 5), 9)
        tiles = detail_fixed_tiles(sea)  # (size, waves) per map: the GL turns the phases to t
        selection = self.select(sea, scene, view, knobs.lod_error_scale, knobs.mesh)
        hulls = hull_boxes(scene, view)
        if self._tables is None:
            self._tables = SeaTables(self.ctx)
        level_z = float(scene.ocean.level - view.position[2])
        table_uniforms = self._tables.fill(self, frame, level_z, 1.5 * float(selection.reach) + abs(level_z))
        used_maps = sum(1 for _, waves in tiles if len(waves))
        waves = self.wave_uniforms(sea, scene, view)  # once per frame, for each program drawn
        # The draw plan follows the selection (one object per view and sea state), the hulls, the
        # tiles' sizes (not their phases), the view's pixel size and the knobs: a still camera over
        # an animating sea plans once.
        plan_key = (self._selection_version, b"".join(h.tobytes() for h in hulls),
                    tuple((size, len(w)) for size, w in tiles), view.tangents, view.width, view.height, level_z,
                    self.skip_minified_maps, self.skip_faded_streaks, self.skip_offshore_land)
        near_hull, maps, streaks, flat, groups, plan_stats = self.memo.get(
            "draw_plan", plan_key, lambda: draw_plan(sea, selection, hulls, tiles, scene, view, level_z, used_maps, PlanSwitches(
                self.skip_minified_maps, self.skip_faded_streaks, self.skip_offshore_land)))
        # Tile averages of the maps some block does not read (empty maps average 0).
        means = detail_means_at(sea, t) if np.any(maps < used_maps) else np.zeros((DETAIL_MAPS, 4))
        self._update_detail(sea, t, resolution, tiles, int(maps.max()) if len(maps) else 0)
        self._maps_written = int(maps.max()) if len(maps) else 0  # the under-water caustics read these
        shared = self._frame_uniforms(frame, sea, waves, tiles, selection, hulls, table_uniforms) if groups else None
        self._underwater = None
        if shared is not None and self._submerged(frame, sea, selection):
            self._underwater = {**shared["values"], **underwater_uniforms(scene, view.position, selection.error_sphere)}
            self._detail_map_values = shared["detail_map"].tobytes()
            shared["values"] = self._underwater
        programs = {}
        lights = local_light_defines(frame.lights)
        for key, *_ in groups:
            if key not in programs:
                with_hulls, m, streak, land = key
                programs[key] = self._configured_program(sea, shared, m, means, with_hulls and bool(hulls),
                                                         streak, lights, land)
        self.stats = {"blocks": int(len(selection.nodes)), "triangles": selection.triangles,
                      "lod_error_px": selection.error_bound_px, "error_sphere_m": selection.error_sphere,
                      "finest_spacing_m": selection.finest_spacing, "waves": sea.n,
                      "detail_resolution": resolution, **plan_stats,
                      "blocks_by_detail_maps": list(plan_stats["blocks_by_detail_maps"]),
                      "foam": bool(shared["foam"]) if shared is not None else False}
        self._detail_synth.copy(self._detail)  # the maps this frame dispatched (_update_detail)
        if len(selection.nodes) == 0:
            return
        if self._underwater is not None:
            self._objects_under_water(targets, table_uniforms, sea)
        targets.scene_fbo.use()
        self.ctx.enable(moderngl.DEPTH_TEST)
        self.ctx.disable(moderngl.BLEND)
        under = self._sees_under_mesh(frame, sea, selection)
        under = under or self._underwater is not None
        if under:
            self.ctx.disable(moderngl.CULL_FACE)
        else:
            # Seen from above, the first surface a ray meets faces the camera (the sea is a height
            # field): back faces (the far slopes of waves) are always hidden, so they are not drawn.
            self.ctx.enable(moderngl.CULL_FACE)
            self.ctx.front_face = "ccw"  # the patch's triangles wind counter-clockwise seen from above
        for key, fan, nodes, slot, data in groups:
            self._vao(programs[key], data, slot, fan).render(moderngl.TRIANGLES, instances=len(nodes))
        self.ctx.disable(moderngl.CULL_FACE)
        self.stats["culled_back_faces"] = not under
        self.stats["underwater"] = self._underwater is not None
        frame.resources["eye_under_water"] = self._underwater is not None  # later passes (precipitation)
        if under:
            self._fill_under_crests(frame, selection, table_uniforms)

    def _frame_uniforms(self, frame, sea, waves: dict, tiles, selection, hulls, table_uniforms) -> dict:
        """This frame's values for every water program (computed once, set on each program drawn), with
        the detail maps, the foam noise and a field's textures bound to their units."""
        scene, view = frame.scene, frame.view
        morph = np.zeros((24, 2), dtype=np.float32)
        morph[:] = np.minimum(selection.morph, 1e30)
        detail_map = np.zeros((3, 3), dtype=np.float32)
        units = {}
        for c, (size, _) in enumerate(tiles):
            detail_map[c] = (1.0 / size, *(np.mod(view.position[:2], size) / size))
            use_texture(self._detail[c], DETAIL_UNIT0 + c)
            units[f"u_detail{c}"] = DETAIL_UNIT0 + c
        wind = scene.weather.wind_speed if scene.ocean.sea_state is None else sea.spectrum.wind
        if self.foam_threshold is None:
            calibration = foam_calibration(sea, wind)
            threshold, unresolved = calibration.threshold, (calibration.unresolved_centre, calibration.freshness)
        else:  # the same centre for both: none (-1), all (10)
            threshold = self.foam_threshold
            unresolved = (threshold + 0.5 * (FOAM_EDGE[0] - FOAM_EDGE[1]), 1.0)
        use_texture(self._foam_noise(), FOAM_NOISE_UNIT)
        values = {**frame.uniforms, **table_uniforms, **glint_light(frame.uniforms), **self._wave_values(sea, waves),
                  "u_morph": morph.tobytes(), **units,
                  "u_min_slope_var": 2e-4 + detail_unresolved_var(sea), "u_foam_jacobian": threshold, "u_foam_unresolved": unresolved,
                  "u_foam_edge": FOAM_EDGE, **foam_frame(scene, view, sea, wind, MAX_WAVES),
                  **shore_uniforms(scene, view, sea), "u_hull_count": len(hulls)}
        if hulls:
            mats = np.zeros((MAX_HULLS, 4, 4), dtype=np.float32)
            mats[: len(hulls)] = np.transpose(np.asarray(hulls), (0, 2, 1))
            values["u_hull_inv"] = mats.tobytes()
        values["u_detail_motion"] = self.detail_motion(scene, view)
        return {"values": values, "detail_map": detail_map,
                "foam": foam_drawn(sea, wind, self.foam_threshold is not None)}

    def _configured_program(self, sea, shared: dict, read_maps: int, means: np.ndarray, with_hulls: bool,
                            foam_streaks: bool, lights: dict, land: bool) -> moderngl.Program:
        """The water program (with or without the hull test, reading the first ``read_maps`` detail
        maps and the tile means of the others, with or without the foam's streak noise, the frame's
        local lights ``lights``: frame.local_light_defines, with or without the shore's land) with this
        frame's uniforms (``_frame_uniforms``) set."""
        program = self._program(sea.field is not None, with_hulls, read_maps, lights,
                                streak_variant(foam_streaks, shared["values"]), shared["values"], land, shared["foam"])
        set_uniforms(program, shared["values"])
        set_uniforms(program, {"u_detail_map": shared["detail_map"][: max(read_maps, 1)].tobytes()})
        mean = program.get("u_detail_mean", None)
        if mean is not None:
            set_uniforms(program, {"u_detail_mean": means[read_maps:read_maps + mean.array_length].astype(np.float32).tobytes()})
        return program

    def capture(self, scene: Scene, mesh: str = "default") -> tuple[lod.LodSelection, np.ndarray]:
        """The displaced mesh the GPU would draw for ``scene``: the water vertex shader run by transform
        feedback on every selected block. Returns (selection, camera-relative positions (N, G+1, G+1, 3)).
        Called outside a frame (tests, quality studies): the pass's context is made current first."""
        from ..camera import make_view
        from ..context import make_current

        make_current(self.ctx)
        view = make_view(scene.camera)
        sea = sea_surface(scene.ocean, scene.weather)
        selection = self.select(sea, scene, view, mesh=mesh)
        program = self.capture_program(sea.field is not None)
        set_uniforms(program, self._wave_values(sea, self.wave_uniforms(sea, scene, view)))
        morph = np.minimum(selection.morph, 1e30).astype(np.float32)
        set_uniforms(program, {"u_morph": morph.tobytes()})
        verts, _ = self._patch_buffer()
        g1 = lod.PATCH_QUADS + 1
        nodes = np.ascontiguousarray(selection.nodes, dtype=np.float32)
        inst = self.ctx.buffer(nodes.tobytes())
        out = self.ctx.buffer(reserve=len(nodes) * g1 * g1 * 12)
        vao = self.ctx.vertex_array(program, [(verts, "2f", "in_grid"), (inst, "4f/i", "in_node")])
        # A draw needs a complete framebuffer even with the rasterizer off (the headless default has none).
        target = self.ctx.simple_framebuffer((1, 1))
        target.use()
        vao.transform(out, mode=moderngl.POINTS, vertices=g1 * g1, instances=len(nodes))
        positions = np.frombuffer(out.read(), dtype=np.float32).reshape(len(nodes), g1, g1, 3).copy()
        for obj in (vao, inst, out, target):
            obj.release()
        return selection, positions

    def _vao(self, program, data: bytes, slot: int = 0, fan: int = -1) -> moderngl.VertexArray:
        """The patch (or a fan of flat blocks, ``_patch_buffer``) drawn once per block of ``data`` (the
        blocks' rows as float32 bytes); each slot (block group drawn in one frame) has its own instance
        buffer, and each view its own slots (``view_state``: channels drawn in turn do not rewrite each
        other's rows every frame)."""
        verts, index = self._patch_buffer(fan)
        buffers, vaos = self.__dict__.setdefault("_instances", {}), self.__dict__.setdefault("_block_vaos", {})
        if slot not in buffers or buffers[slot].size < len(data):
            if slot in buffers:
                buffers.pop(slot).release()
                for key in [k for k in vaos if k[1] == slot]:
                    vaos.pop(key).release()
            buffers[slot] = self.ctx.buffer(reserve=max(len(data), 4096), dynamic=True)
        write_buffer(buffers[slot], data)
        key = (id(program), slot, fan)
        if key not in vaos:
            vaos[key] = self.ctx.vertex_array(program, [(verts, "2f", "in_grid"), (buffers[slot], "4f/i", "in_node")],
                                              index_buffer=index)
        return vaos[key]
