"""Sky pass: per-pixel sky radiance, sun, moon and cirrus into the pixels no surface covered, then
the bright stars as points (only when they could show: sun below -2 deg)."""

from __future__ import annotations

import math
from functools import lru_cache

import moderngl
import numpy as np

from ...astro import star_field
from .. import depth
from ..bindings import PASS_UNITS, use_texture
from ..memo import view_key
from ..passes import RenderPass
from ..shaders import set_uniforms, uniform_inputs
from .frame_sky import held_haze_table
from .sky_view import SKY_VIEW_SIZE

STAR_POINT_PX = 2.0
# The cirrus layer is evaluated once per frame on a grid this many times coarser per axis than the
# frame (cirrus_table.glsl), 1 = per pixel in the sky pass (the reference for the picture error).
CIRRUS_TABLE_SCALE = 2
CIRRUS_TABLE_UNIT = PASS_UNITS["CIRRUS_TABLE"]    # (cloud radiance x alpha x T, alpha)
CIRRUS_HIDE_UNIT = PASS_UNITS["CIRRUS_HIDE"]      # (alpha x T): how much of the sky behind the layer it hides
SKY_HAZY_UNIT = PASS_UNITS["SKY_HAZY"]            # the sky through the haze layer on the sky-view map (sky_hazy.glsl)
SKY_HAZY_MOON_UNIT = PASS_UNITS["SKY_HAZY_MOON"]  # its moon term, one column
# Its size (azimuth from the sun, elevation): the clear sky-view table's, whose texel centres it
# reads exactly; against haze_sky() per pixel within 1 level where it is used (hazy_table_holds).
SKY_HAZY_SIZE = SKY_VIEW_SIZE

# Texels outside the polygon hold zero, as the shader would compute there, so the sky pass's
# bilinear lookup needs no margin; one texel covers float32 rounding in the shader's ray.
CIRRUS_POLYGON_MARGIN_TEXELS = 1.0
CIRRUS_TABLE_MIN_WIDTH = 320  # px, the narrowest table
# The table is drawn again only when an input other than the layer's drift changed, or when the
# drift (wind, camera travel) since its last draw could have moved the layer by more than this
# many frame pixels anywhere in view (cirrus_drift_px, a bound); 0 draws it whenever anything moved.
CIRRUS_REDRAW_PX = 0.25
STARS_BELOW_SUN_ELEVATION = -2.0  # deg; above this the day sky hides even Sirius


def hazy_table_holds(uniforms: dict) -> bool:
    """Whether the sky pass reads the haze from the table (sky_hazy.glsl): with a haze layer, from a
    camera inside it or at most one scale height above its top. From higher up the layer's limb is a
    band a fraction of a degree tall just above the horizon, finer than the table's rows there, and
    haze_sky() stays per pixel (measured against it at 640x360: within 1 level up to one scale
    height, 1 pixel at 2 levels from 1 km in the default haze; from 10 km up to 10 levels, and 13-20
    levels from 50-300 m above a fog top)."""
    if uniforms.get("u_sky_model") != 1 or uniforms["u_haze_beta"][1] <= 0.0:
        return False
    height = uniforms["u_camera_altitude"] - uniforms["u_haze_base"]
    return height <= uniforms["u_haze_top"] + uniforms["u_haze_edge"]


# Angular half-size of the boxes the disks are drawn in: the disk (sun 0.27 deg, moon 0.26 deg)
# plus the sun's 1.5-pixel footprint tent is added in pixels by disk_box().
SUN_BOX_RAD = math.radians(0.3)
MOON_BOX_RAD = math.radians(0.3)


def disk_box(frame, direction, radius_rad: float) -> tuple[int, int, int, int] | None:
    """Scissor box (x, y, w, h, pixels, origin bottom-left) around a disk of angular radius
    ``radius_rad`` centred on ``direction``; None when it is off screen or behind the camera."""
    view = frame.view
    d = np.asarray(direction, dtype=np.float64)
    clip = np.asarray(view.view_proj, dtype=np.float64) @ np.array([d[0], d[1], d[2], 0.0])
    if clip[3] <= 1e-9:
        return None
    w, h = view.width, view.height
    x = (clip[0] / clip[3] * 0.5 + 0.5) * w
    y = (clip[1] / clip[3] * 0.5 + 0.5) * h
    pixel = 2.0 * math.tan(math.radians(frame.scene.camera.fov_y) / 2.0) / h  # rad per px at the centre
    # Off the axis a radian spans more pixels (1/cos^2 of the angle off the axis): take the box
    # twice the disk (up to 60 deg off-axis) plus the 1.5-px footprint and a pixel of filtering.
    r = 2.0 * radius_rad / pixel + 3.0
    x0, y0 = int(math.floor(x - r)), int(math.floor(y - r))
    x1, y1 = int(math.ceil(x + r)), int(math.ceil(y + r))
    x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
    if x1 <= x0 or y1 <= y0:
        return None
    return (x0, y0, x1 - x0, y1 - y0)


def cirrus_polygon(frame, table_size: tuple[int, int]) -> np.ndarray | None:
    """The part of the frame (uv in [0, 1]^2, a convex polygon as a triangle list, float32 (n, 2))
    whose view rays can meet the cirrus layer, grown by CIRRUS_POLYGON_MARGIN_TEXELS texels of a
    table of ``table_size``; None when no ray can. From below the layer a ray meets it only when it
    misses the earth: normalised dir.z >= mu_h, the cosine of the camera's geometric horizon
    (cirrus.glsl cirrus_distance). The unnormalised ray d(u, v) = F + t_x R + t_y U is linear in
    uv and |d| <= d_max (its largest value over the frame, at a corner), so the half-plane
    d.z(u, v) >= mu_h d_max (mu_h <= 0) holds every such ray: outside it the layer is zero. From
    above the layer (or on it) the whole frame is returned."""
    u = frame.uniforms
    view = frame.view
    return _cirrus_polygon(np.asarray(view.rotation, dtype=np.float64).tobytes(), tuple(float(t) for t in view.tangents),
                           float(u["u_bottom_radius_km"]), float(u["u_camera_altitude"]),
                           float(u["u_cirrus_altitude_km"]), tuple(table_size))


# Per exact view basis, frustum, radii and table size (all its inputs): a still camera finds its
# polygon once. The array is shared, so read-only.
@lru_cache(maxsize=16)
def _cirrus_polygon(rotation: bytes, tangents: tuple, bottom: float, camera_altitude_m: float,
                    cirrus_altitude_km: float, table_size: tuple) -> np.ndarray | None:
    r_cam = bottom + max(camera_altitude_m * 1e-3, 1e-3)
    r_layer = bottom + cirrus_altitude_km
    corners = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    rot = np.frombuffer(rotation, dtype=np.float64).reshape(3, 3)
    right, forward, up = rot[:, 0], rot[:, 1], rot[:, 2]
    left_t, right_t, bottom_t, top_t = tangents

    def ray(uv):
        tx = left_t + uv[..., :1] * (right_t - left_t)
        ty = bottom_t + uv[..., 1:] * (top_t - bottom_t)
        return forward + tx * right + ty * up

    if r_cam >= r_layer:
        poly = corners
    else:
        mu_h = -math.sqrt(max(1.0 - (bottom / r_cam) ** 2, 0.0))
        d_max = float(np.linalg.norm(ray(corners), axis=1).max())
        z0 = ray(np.zeros(2))[2]
        dz_du = (right_t - left_t) * right[2]
        dz_dv = (top_t - bottom_t) * up[2]
        margin = CIRRUS_POLYGON_MARGIN_TEXELS * (abs(dz_du) / table_size[0] + abs(dz_dv) / table_size[1])
        # Keep f(u, v) = z0 + dz_du u + dz_dv v - (mu_h d_max - margin) >= 0 (Sutherland-Hodgman).
        c = z0 - (mu_h * d_max - margin)
        f = c + dz_du * corners[:, 0] + dz_dv * corners[:, 1]
        kept = []
        for i in range(4):
            a, b, fa, fb = corners[i], corners[(i + 1) % 4], f[i], f[(i + 1) % 4]
            if fa >= 0.0:
                kept.append(a)
            if (fa >= 0.0) != (fb >= 0.0):
                kept.append(a + (b - a) * (fa / (fa - fb)))
        if len(kept) < 3:
            return None
        poly = np.array(kept)
    tris = np.array([[poly[0], poly[i], poly[i + 1]] for i in range(1, len(poly) - 1)]).reshape(-1, 2).astype("f4")
    tris.flags.writeable = False
    return tris


def cirrus_drift_px(frame, offset_a, offset_b) -> float:
    """An upper bound on how far (frame pixels) the cirrus pattern seen in this view moves when the
    layer's noise offset (cirrus.glsl u_cirrus_offset, noise units) goes from ``offset_a`` to
    ``offset_b``, all else equal: the pattern shifts by s km along the layer; a point of it at
    distance t from the camera turns by at most s / t rad; t >= t_min, the layer's distance along
    the view ray that meets it nearest (the frame's highest ray from below the layer, monotone:
    cirrus_distance falls as dir.z rises; from above, the vertical distance); a turn of d rad moves
    a rectilinear image point by at most d (1 + tan^2) tangent units, tan at the frame's farthest
    corner, times the pixels per tangent unit of the finer axis."""
    u = frame.uniforms
    period = float(u["u_cirrus_period"])
    d = np.asarray(offset_b, dtype=np.float64) - np.asarray(offset_a, dtype=np.float64)
    d = (d + 0.5 * period) % period - 0.5 * period  # the offsets wrap on the noise period
    s_km = float(np.hypot(d[0], d[1])) * float(u["u_cirrus_feature_km"])
    if s_km == 0.0:
        return 0.0
    bottom = float(u["u_bottom_radius_km"])
    r_cam = bottom + max(float(u["u_camera_altitude"]) * 1e-3, 1e-3)
    r_layer = bottom + float(u["u_cirrus_altitude_km"])
    t_min = max(abs(r_layer - r_cam), 1e-3)  # km; a camera in the layer: any drift redraws
    left_t, right_t, bottom_t, top_t = (float(t) for t in frame.view.tangents)
    if r_cam < r_layer:
        z = _highest_ray_z(np.asarray(frame.view.rotation, dtype=np.float64).tobytes(), left_t, right_t, bottom_t, top_t)
        b = r_cam * z
        t_min = max(t_min, -b + math.sqrt(max(b * b - (r_cam - r_layer) * (r_cam + r_layer), 0.0)))
    tan2 = max(left_t * left_t, right_t * right_t) + max(bottom_t * bottom_t, top_t * top_t)
    px_per_tan = max(frame.view.width / (right_t - left_t), frame.view.height / (top_t - bottom_t))
    return s_km / t_min * (1.0 + tan2) * px_per_tan


@lru_cache(maxsize=16)  # per exact view basis and frustum: a still camera finds it once
def _highest_ray_z(rotation: bytes, left_t: float, right_t: float, bottom_t: float, top_t: float) -> float:
    """The largest z of a normalised view ray over the frame (``rotation``: the view's float64
    basis, columns right, forward, up): 1 when the zenith is in view, else the largest over its four
    edges (on an edge a + s b, z/|d| has one stationary point, in closed form)."""
    rot = np.frombuffer(rotation, dtype=np.float64).reshape(3, 3)
    right, forward, up = rot[:, 0], rot[:, 1], rot[:, 2]
    zf = float(forward[2])
    if zf > 0.0:
        tx, ty = float(right[2]) / zf, float(up[2]) / zf  # the zenith's tangent coordinates
        if left_t <= tx <= right_t and bottom_t <= ty <= top_t:
            return 1.0
    corners = [forward + tx * right + ty * up for tx, ty in
               ((left_t, bottom_t), (right_t, bottom_t), (right_t, top_t), (left_t, top_t))]
    best = -1.0
    for i in range(4):
        a, e = corners[i], corners[(i + 1) % 4] - corners[i]
        cands = [0.0, 1.0]
        den = e[2] * (a @ e) - a[2] * (e @ e)
        if den != 0.0:
            s_star = (a[2] * (a @ e) - e[2] * (a @ a)) / den
            if 0.0 < s_star < 1.0:
                cands.append(s_star)
        for s_ in cands:
            d = a + s_ * e
            best = max(best, float(d[2] / np.linalg.norm(d)))
    return best


def surface_below(scene) -> bool:
    """The sea or the ground is drawn below the camera (sky pixels are then above its horizon)."""
    z = scene.camera.position[2]
    if scene.ocean.enabled:
        return z > scene.ocean.level
    return scene.ground.enabled and z > scene.ground.level


class SkyPass(RenderPass):
    name = "sky"
    view_state = ("_held_targets", "_cirrus_fbo", "_cirrus_fbo_key", "_cirrus_drawn")  # the cirrus table

    def execute(self, frame, targets) -> None:
        model = frame.scene.atmosphere.model
        defines = {"SKY_" + model.upper(): 1}
        if frame.scene.weather.cirrus_coverage > 0.0:
            defines["CIRRUS"] = 1  # compiled in only when drawn: llvmpipe pays for it even when skipped
            # Frames narrower than 2 x CIRRUS_TABLE_MIN_WIDTH keep the per-pixel layer: on a coarse
            # table the streaks near the horizon fall under a texel (256 px wide: 32 dB) and the
            # noise costs little there anyway.
            if self.cirrus_scale <= 1 or targets.size[0] // self.cirrus_scale < CIRRUS_TABLE_MIN_WIDTH:
                defines["CIRRUS_PER_PIXEL"] = 1
            else:
                self._cirrus_table(frame, model, targets)
        if surface_below(frame.scene):
            defines["SURFACE_BELOW"] = 1
        if self.hazy_table and hazy_table_holds(frame.uniforms):
            hazy, moon = self._hazy_table(frame)
            use_texture(hazy, SKY_HAZY_UNIT)
            use_texture(moon, SKY_HAZY_MOON_UNIT)
            defines["SKY_HAZY_TABLE"] = 1
            if float(np.float32(frame.uniforms["u_moon_dir"][2])) > 0.0:  # haze_phases' own test
                defines["SKY_HAZY_MOON"] = 1
        program = self.programs.program("common/fullscreen.vert.glsl", "sky/sky.glsl", defines)
        set_uniforms(program, frame.uniforms)
        if "SKY_HAZY_TABLE" in defines:
            set_uniforms(program, {"u_sky_hazy": SKY_HAZY_UNIT, "u_sky_hazy_moon": SKY_HAZY_MOON_UNIT})
        targets.scene_fbo.use()
        self.ctx.enable(moderngl.DEPTH_TEST)
        self.ctx.depth_func = depth.AT_INFINITY  # only where nothing nearer was drawn
        self.fullscreen(program)
        self._disks(frame, defines, targets)
        if frame.celestial.sun_elevation < STARS_BELOW_SUN_ELEVATION:
            self._stars(frame, model)
        self.ctx.depth_func = depth.NEAREST_WINS

    hazy_table = True  # False: haze_sky() per pixel (the reference of the table's error)
    hazy_fills = 0  # tables filled (counted for the tests)

    def _hazy_table(self, frame) -> tuple[moderngl.Texture, moderngl.Texture]:
        """The sky through the haze layer on the sky-view map and its moon column (sky_hazy.glsl),
        filled again only when one of its inputs changed: the clear sky-view table or a uniform the
        fill reads (the haze, its light, the camera's altitude, the sun and the moon), or the fog
        layer's light table it samples (made from more than those uniforms: the ground's albedo)."""
        program = self.programs.compute("sky/sky_hazy.glsl")
        sky_view = frame.resources["sky_view"]
        haze_table = held_haze_table(self.ctx)
        key = (id(sky_view), sky_view.fills, uniform_inputs(program, frame.uniforms),
               None if haze_table is None else haze_table[1])
        if getattr(self, "_hazy_tex", None) is None:
            self._hazy_tex = (self.ctx.texture(SKY_HAZY_SIZE, 4, dtype="f4"),
                              self.ctx.texture((1, SKY_HAZY_SIZE[1]), 4, dtype="f4"))
            for tex in self._hazy_tex:
                tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
                tex.repeat_x = tex.repeat_y = False
        if key != getattr(self, "_hazy_key", None):
            set_uniforms(program, frame.uniforms)
            for binding, tex in enumerate(self._hazy_tex):
                tex.bind_to_image(binding, read=False, write=True)
            program.run((SKY_HAZY_SIZE[0] + 7) // 8, (SKY_HAZY_SIZE[1] + 7) // 8, 1)
            self.ctx.memory_barrier()
            self._hazy_key = key
            self.hazy_fills += 1
        return self._hazy_tex

    cirrus_scale = CIRRUS_TABLE_SCALE
    cirrus_redraw_px = CIRRUS_REDRAW_PX
    cirrus_draws = 0  # tables drawn (counted for the tests and the bench)

    def _disks(self, frame, defines: dict, targets) -> None:
        """The sun's and the moon's disks, added inside a scissor box around each (sky.glsl SKY_DISKS)."""
        boxes = self._disk_boxes(frame)
        if not boxes:
            return
        program = self.programs.program("common/fullscreen.vert.glsl", "sky/sky.glsl", {**defines, "SKY_DISKS": 1})
        set_uniforms(program, frame.uniforms)
        self.ctx.enable(moderngl.BLEND)
        self.ctx.blend_func = moderngl.ONE, moderngl.ONE
        fbo = targets.scene_fbo
        try:
            for box in boxes:
                fbo.scissor = box
                self.fullscreen(program)
        finally:
            fbo.scissor = None
            self.ctx.disable(moderngl.BLEND)

    def _disk_boxes(self, frame) -> list:
        """The sun's and the moon's scissor boxes on screen, kept per exact view, directions and
        field of view (disk_box's inputs)."""
        c = frame.celestial
        key = (view_key(frame.view), frame.scene.camera.fov_y, tuple(c.sun_dir), tuple(c.moon_dir))
        held = getattr(self, "_held_disk_boxes", None)
        if held is None or held[0] != key:
            boxes = [b for b in (disk_box(frame, c.sun_dir, SUN_BOX_RAD), disk_box(frame, c.moon_dir, MOON_BOX_RAD))
                     if b is not None]
            held = self._held_disk_boxes = (key, boxes)
        return held[1]

    def _cirrus_table(self, frame, model: str, targets) -> None:
        """Draw the cirrus layer at 1/cirrus_scale resolution into two float textures on units 7 and
        6 (cirrus_table.glsl), only inside the polygon of the frame whose rays can meet the layer
        (cirrus_polygon; the rest cleared to no cloud: in the demo half the frame is sea). Drawn per
        change, not per frame: kept while every input but the layer's drift is the same as at its
        last draw and the drift since then moves the layer by at most cirrus_redraw_px pixels."""
        w, h = targets.size
        size = (max(w // self.cirrus_scale, 1), max(h // self.cirrus_scale, 1))
        layer = self.held_target("cirrus", size, "f4")[0]
        hide = self.held_target("cirrus_hide", size, "f4")[0]
        key = (id(layer), id(hide))
        if getattr(self, "_cirrus_fbo_key", None) != key:
            if getattr(self, "_cirrus_fbo", None) is not None:
                self._cirrus_fbo.release()
            self._cirrus_fbo = self.ctx.framebuffer([layer, hide])
            self._cirrus_fbo_key = key
        tris = cirrus_polygon(frame, size)
        program = self.programs.program("sky/cirrus_table.vert.glsl", "sky/cirrus_table.glsl",
                                        {"SKY_" + model.upper(): 1})
        offset = frame.uniforms["u_cirrus_offset"]
        inputs = self._cirrus_inputs(frame, program, key, size, tris)
        held = getattr(self, "_cirrus_drawn", None)
        if (held is None or held[0] != inputs
                or cirrus_drift_px(frame, held[1], offset) > self.cirrus_redraw_px):
            self._draw_cirrus_table(frame, program, size, tris)
            self._cirrus_drawn = (inputs, offset)
        use_texture(layer, CIRRUS_TABLE_UNIT)
        use_texture(hide, CIRRUS_HIDE_UNIT)

    def _cirrus_inputs(self, frame, program, key, size, tris) -> tuple:
        """Everything the cirrus table is drawn from except the layer's offset (its drift): the
        values of the table shader's active uniforms (exposure is not one: the table is radiance),
        the atmosphere tables it samples, its targets, size and polygon."""
        tables = frame.resources.get("atmosphere_tables")
        return (id(program), key, size, None if tris is None else tris.tobytes(),
                None if tables is None else (id(tables), tables.key),
                uniform_inputs(program, frame.uniforms, skip=("u_cirrus_offset",)))

    def _draw_cirrus_table(self, frame, program, size, tris) -> None:
        fbo = self._cirrus_fbo
        fbo.use()
        fbo.clear(0.0, 0.0, 0.0, 0.0)
        self.cirrus_draws += 1
        if tris is not None:
            set_uniforms(program, {**frame.uniforms, "u_cirrus_table_size": (float(size[0]), float(size[1]))})
            if getattr(self, "_cirrus_vbo", None) is None:
                self._cirrus_vbo = self.ctx.buffer(reserve=9 * 2 * 4)  # a pentagon at most: 3 triangles of 2 floats
                self._cirrus_vaos: dict = {}
            self._cirrus_vbo.write(tris.tobytes())
            vao = self._cirrus_vaos.get(id(program))
            if vao is None:
                vao = self._cirrus_vaos[id(program)] = self.ctx.vertex_array(
                    program, [(self._cirrus_vbo, "2f", "in_uv")])
            self.ctx.disable(moderngl.DEPTH_TEST)
            vao.render(moderngl.TRIANGLES, vertices=len(tris))

    def _stars(self, frame, model: str) -> None:
        scene = frame.scene
        stars = star_field(scene.time.utc, scene.location.lat, scene.location.lon)
        program = self.programs.program("sky/stars.glsl", "sky/stars.glsl", {"SKY_" + model.upper(): 1})
        view = frame.view
        pixel = 2.0 * math.tan(math.radians(scene.camera.fov_y) / 2.0) / view.height  # rad per px
        set_uniforms(program, {**frame.uniforms, "u_star_pixel_solid_angle": pixel * pixel * STAR_POINT_PX**2})
        data = np.hstack([stars.directions, stars.illuminance[:, None]]).astype("f4")
        if getattr(self, "_star_vbo", None) is None or self._star_vbo.size != data.nbytes:
            self._star_vbo = self.ctx.buffer(reserve=data.nbytes)
            self._star_vaos: dict = {}
        if id(program) not in self._star_vaos:
            self._star_vaos[id(program)] = self.ctx.vertex_array(
                program, [(self._star_vbo, "3f 1f", "in_dir", "in_lux")])
        self._star_vao = self._star_vaos[id(program)]
        self._star_vbo.write(data.tobytes())
        self.ctx.point_size = STAR_POINT_PX
        self.ctx.enable(moderngl.BLEND)
        self.ctx.blend_func = moderngl.ONE, moderngl.ONE
        self._star_vao.render(moderngl.POINTS, vertices=len(data))
        self.ctx.disable(moderngl.BLEND)

