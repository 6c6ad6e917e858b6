"""The per-frame aerial-perspective table: a camera-frustum volume (screen x, y times log-distance
slices; Hillaire 2020's "aerial perspective LUT") of the optical depth and the mean in-scattered
source of the view ray to each node, filled by a small compute pass from the one atmosphere
library (``apply_aerial_perspective`` in common/atmosphere.glsl: the clear air through the sky-view
table plus the fog/haze layer) and read by the lit passes with one lookup
(``aerial_perspective(L, rel)`` in common/aerial_table.glsl).

It is refilled only when what the fill reads changed: the camera's orientation, frustum and
altitude, the sun and moon, the fog/haze layer (visibility, precipitation fog, its light), the
sky-view table or the atmosphere tables, or the range. A camera moving level without turning, a
stream at a fixed time and weather reuse it. A turning camera's next table is filled ahead, in parts over
frames, while the current one serves (AerialTable.update).

What stays per pixel: the glow of local lights in fog (post/halos.py) — it depends on each light's
position against the pixel's ray and surface distance, which no table over the frustum resolves at
the sizes that pay off — and the sea, which has its own tables (render/water/sea_tables.glsl).

Any pass may read it: ``frame_aerial_table(frame)`` fills it (once per frame at most) and binds it
on units 18/19; the shader includes common/aerial_table.glsl after common/atmosphere.glsl.
"""

from __future__ import annotations

import math
import weakref

import moderngl
import numpy as np

from ..bindings import FRAME_UNITS, use_texture
from ..shaders import ProgramCache, set_uniforms, uniform_inputs
from ..resident import resident
from ..sky.frame_sky import held_haze_table

AERIAL_UNITS = {"u_aerial_tau": FRAME_UNITS["AERIAL_TAU"], "u_aerial_source": FRAME_UNITS["AERIAL_SOURCE"]}
# (screen x nodes, screen y nodes, distance slices) over the view widened by AERIAL_GUARD on each
# side: from the error-vs-time check in docs/quality.md ("Aerial-perspective table"); presets do not
# change it (the fill runs only when the view leaves the table or the light or fog change).
AERIAL_SIZE = (80, 45, 32)
AERIAL_GUARD = 0.1  # of the frustum's width (tangent) added on each side: a turning camera refills less often
AERIAL_ZOOM = 0.7     # refill when the view is narrower than this fraction of the table's own view
# A turning camera's next table is started once its view has moved this fraction of the guard band
# toward an edge, and filled in AERIAL_PARTS parts, one a frame (at 2 deg a frame and a 60 deg view
# the guard band is ~4.7 deg: started after ~1.6 deg, swapped in ~2 frames later).
AERIAL_AHEAD = 1.0 / 3.0
AERIAL_PARTS = 3
VIEW_UNIFORMS = ("u_camera_right", "u_camera_up", "u_camera_forward", "u_frustum_tangents", "u_resolution")
AERIAL_D0 = 1.0         # m, the first slice; nearer, tau scales with distance (exact in a homogeneous medium)
AERIAL_MIN_RANGE = 100.0  # m
AERIAL_MAX_RANGE = 2.0e7  # m (beyond the ground's horizon from 10,000 km)
# Above this height over the ground (or the sea) the passes keep the per-pixel function: seen from
# altitude, a ray's optical depth piles up in the last few km before the ground (scale heights
# 1.2 and 8 km), which slices uniform in log distance from the camera do not resolve (ground plane,
# day, pitch -20: 55.7 dB / max 2 levels at 1 km, 49.0 / 8 at 3 km, 32.2 / 49 at 10 km).
AERIAL_MAX_HEIGHT = 1000.0  # m
EARTH_SPHERE_RADIUS = 6.371e6  # m, as common/earth.glsl


def horizon_distance(height_m: float) -> float:
    """Distance (m) to the horizon of a sphere of the earth's radius from height_m above it."""
    h = max(height_m, 1.0)
    return math.sqrt(h * (2.0 * EARTH_SPHERE_RADIUS + h))


def table_range(scene, view) -> float:
    """The farthest distance the table must hold (m): the ground's or the sea's horizon, every
    entity (its distance + its scale-weighted reach, generously) within the draw distance, and
    every effect; rounded up to a power of 2 so a slowly moving camera keeps the same slices."""
    z = float(view.position[2])
    far = [horizon_distance(z - (scene.ground.level if scene.ground.enabled else 0.0)),
           horizon_distance(z)]
    for entity in scene.entities:
        if entity.visible:
            d = _distance(entity.position, view.position)
            reach = 50.0 * max(entity.scale)
            if d - reach <= scene.camera.far:
                far.append(d + reach)
    for effect in scene.effects:
        far.append(_distance(effect.position, view.position) + 100.0)
    d = min(max(max(far), AERIAL_MIN_RANGE), AERIAL_MAX_RANGE)
    return float(2.0 ** math.ceil(math.log2(d)))


def _distance(position, origin: np.ndarray) -> float:
    """|position - origin| as np.linalg.norm finds it (its dot product and root), without its call."""
    v = np.asarray(position) - origin
    return math.sqrt(float(v @ v))


def table_map(d_max: float, slices: int, d0: float = AERIAL_D0) -> tuple[float, float, float, float]:
    """u_aerial_map: d0 (m), log2 of the slice ratio q, q, number of slices (d_k = d0 q^k)."""
    log2_q = math.log2(d_max / d0) / (slices - 1)
    return (d0, log2_q, 2.0 ** log2_q, float(slices))


class AerialTable:
    """Resident table textures of one GL context."""

    _resident: "weakref.WeakKeyDictionary[moderngl.Context, AerialTable]" = weakref.WeakKeyDictionary()

    def __init__(self, ctx: moderngl.Context, size=AERIAL_SIZE):
        self.ctx = ctx
        self.size = tuple(int(n) for n in size)
        if min(self.size) < 2:
            raise ValueError(f"aerial table size {self.size}: at least 2 nodes per axis")
        self.programs = ProgramCache(ctx)
        self.textures = {}
        for name in AERIAL_UNITS:
            tex = ctx.texture3d(self.size, 4, dtype="f4")
            tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
            tex.repeat_x = tex.repeat_y = tex.repeat_z = False
            self.textures[name] = tex
        # The fill writes these storage buffers (llvmpipe's 3D image stores are ~15x slower), then
        # they are copied into the textures (a pixel-unpack copy).
        self.buffers = {name: ctx.buffer(reserve=4 * 4 * math.prod(self.size)) for name in AERIAL_UNITS}
        self.map = table_map(1e4, self.size[2])
        self._frame = None  # (right, up, forward, tangents) the table was filled for
        self._key = None
        self._pending = None  # a fill under way in the buffers (AerialTable._start)
        self._inside: dict = {}  # id(table frame) -> (the frame, {(view, margin): view_inside})
        self.fills = 0

    @classmethod
    def get(cls, ctx: moderngl.Context, size=AERIAL_SIZE) -> "AerialTable":
        return resident(cls, ctx, size)

    def update(self, uniforms: dict, d_max: float, inputs: tuple = ()) -> None:
        """Fill the table for these frame uniforms unless it already holds them. The table has its
        own frame: the camera's basis at the fill, its frustum widened by AERIAL_GUARD on every side,
        so a turning camera reuses it while its view stays inside that frustum and is not zoomed in
        past AERIAL_ZOOM (resolution). Everything else the fill reads is the key: every uniform of
        the fill program (a new input of the atmosphere library joins it by itself), the range, and
        ``inputs`` (versions of the textures it samples).

        A turning camera: once its view has moved AERIAL_AHEAD of the guard band toward an edge, the
        next table (turned ahead of the view: _start) is filled in AERIAL_PARTS parts, one a frame,
        into the storage buffers while the textures keep serving, and swapped in when done; a view
        that leaves the table first finishes it at once (or, when not inside it either, fills anew).
        Every frame's view lies inside the table it reads."""
        prog = self.programs.compute("common/aerial_table.comp.glsl")
        values = {**uniforms, "u_aerial_map": table_map(d_max, self.size[2])}
        key = (inputs, uniform_inputs(prog, values, skip=VIEW_UNIFORMS))
        pending = self._pending if self._pending is not None and self._pending["key"] == key else None
        inside = self._view_inside
        if key == self._key and self._frame is not None and inside(self._frame, uniforms):
            if pending is not None and not inside(pending["frame"], uniforms):
                pending = self._pending = None  # the turn reversed: the table ahead would not hold the view
            if pending is None and not inside(self._frame, uniforms, 1.0 - AERIAL_AHEAD):
                pending = self._start(values, key, self._frame)
            if pending is not None:
                self._fill_part(prog, pending, 1)
                if self._pending is None and not inside(self._frame, uniforms, 1.0 - AERIAL_AHEAD):
                    # Swapped in already turned past it: the next one's parts from the next frame.
                    self._start(values, key, self._frame)
            return
        if pending is None or not inside(pending["frame"], uniforms):
            pending = self._start(values, key)
        self._fill_part(prog, pending, AERIAL_PARTS - pending["done"])

    def _view_inside(self, table_frame, uniforms: dict, margin: float = 0.0) -> bool:
        """view_inside, kept per table frame (the object itself, held) and exact view (the camera
        uniforms it reads) and margin: a still camera tests each once."""
        view = tuple(uniforms[name] for name in VIEW_UNIFORMS[:4])
        held = self._inside.get(id(table_frame))
        if held is None or held[0] is not table_frame:
            if len(self._inside) >= 4:  # the table's frame and the one being filled ahead
                self._inside.clear()
            held = self._inside[id(table_frame)] = (table_frame, {})
        key = (view, margin)
        try:
            hit = held[1].get(key)
        except TypeError:  # a camera given as arrays: tested, not kept
            return view_inside(table_frame, uniforms, margin)
        if hit is None:
            if len(held[1]) >= 16:
                held[1].clear()
            hit = held[1][key] = view_inside(table_frame, uniforms, margin)
        return hit

    def _start(self, values: dict, key, ahead_of=None) -> dict:
        """A fill for the view in these uniforms, not yet run: its frame, map, uniforms and parts done.
        ``ahead_of``: the table the view is turning out of; the new one is turned on by twice the
        rotation from that table's frame to the view (the turn goes on while the parts are filled:
        centred on the view, or turned on once, a table was left 1-2 frames after it was swapped in
        at 2 deg a frame, and its last parts ran at once)."""
        basis = [np.asarray(values[name], np.float64) for name in VIEW_UNIFORMS[:3]]
        if ahead_of is not None:
            view, old = np.column_stack(basis), np.column_stack(ahead_of[:3])
            lead = view @ old.T  # rotation taking the old table's axes to the view's
            basis = list((lead @ lead @ view).T)  # twice on: the parts take two more frames
        l, r, b, t = values["u_frustum_tangents"]
        gx, gy = AERIAL_GUARD * (r - l), AERIAL_GUARD * (t - b)
        frame = (*basis, (l - gx, r + gx, b - gy, t + gy))
        self._pending = {"frame": frame, "key": key, "map": values["u_aerial_map"], "done": 0,
                         "values": {**values, **fill_view(frame), "u_aerial_size": self.size}}
        return self._pending

    def _fill_part(self, prog, pending: dict, parts: int) -> None:
        """Run the next ``parts`` of the pending fill (of AERIAL_PARTS: bands of 8-row work groups);
        when it is complete, copy it into the textures and make it the table."""
        groups_y = -(-self.size[1] // 8)
        first = groups_y * pending["done"] // AERIAL_PARTS
        pending["done"] = min(pending["done"] + parts, AERIAL_PARTS)
        last = groups_y * pending["done"] // AERIAL_PARTS
        if last > first:
            set_uniforms(prog, {**pending["values"], "u_aerial_row0": 8 * first})
            for binding, name in enumerate(AERIAL_UNITS):
                self.buffers[name].bind_to_storage_buffer(binding)
            prog.run(-(-self.size[0] // 8), last - first, 1)
            self.ctx.memory_barrier()
        if pending["done"] < AERIAL_PARTS:
            return
        for name in AERIAL_UNITS:
            self.textures[name].write(self.buffers[name])
        self._frame, self.map, self._key = pending["frame"], pending["map"], pending["key"]
        self._pending = None
        self.fills += 1

    def bind(self) -> None:
        for name, unit in AERIAL_UNITS.items():
            use_texture(self.textures[name], unit)

    def uniforms(self) -> dict:
        right, up, forward, tangents = self._frame
        return {**AERIAL_UNITS, "u_aerial_map": self.map, "u_aerial_right": tuple(right), "u_aerial_up": tuple(up),
                "u_aerial_forward": tuple(forward), "u_aerial_tangents": tuple(tangents)}

    def release(self) -> None:
        for tex in self.textures.values():
            tex.release()
        for buf in self.buffers.values():
            buf.release()


def fill_view(table_frame) -> dict:
    """The camera uniforms the fill's view_ray() reads, set to the table's own frame."""
    right, up, forward, tangents = table_frame
    return {"u_camera_right": tuple(right), "u_camera_up": tuple(up), "u_camera_forward": tuple(forward),
            "u_frustum_tangents": tuple(tangents)}


def view_inside(table_frame, uniforms: dict, margin: float = 0.0) -> bool:
    """Whether the frame's view lies inside the table's frustum (its four corner rays project
    within the table's tangents, each side moved in by ``margin`` of the guard band's width) and is not
    zoomed in past AERIAL_ZOOM of the table's own view."""
    right, up, forward, (l, r, b, t) = table_frame
    cr, cu, cf = (np.asarray(uniforms[name], np.float64) for name in VIEW_UNIFORMS[:3])
    vl, vr, vb, vt = uniforms["u_frustum_tangents"]
    inner = 1.0 / (1.0 + 2.0 * AERIAL_GUARD)
    if (vr - vl) < AERIAL_ZOOM * inner * (r - l) or (vt - vb) < AERIAL_ZOOM * inner * (t - b):
        return False
    inset = margin * AERIAL_GUARD * inner
    l, r, b, t = l + inset * (r - l), r - inset * (r - l), b + inset * (t - b), t - inset * (t - b)
    corners = np.array([cf + x * cr + y * cu for x in (vl, vr) for y in (vb, vt)])
    z = corners @ forward
    if np.any(z <= 1e-6):
        return False
    tx, ty = (corners @ right) / z, (corners @ up) / z
    return bool(np.all((tx >= l) & (tx <= r) & (ty >= b) & (ty <= t)))


def table_serves(scene, view, size=AERIAL_SIZE) -> bool:
    """Whether the table serves this view: the camera at most AERIAL_MAX_HEIGHT above the ground
    plane (or the sea level when there is no ground), where it holds its error bound, and a frame of
    at least as many pixels as the table has nodes — a node costs about what a pixel's per-pixel
    evaluation costs (fill 21–30 ms for 115,200 nodes, night_fire's per-pixel aerial perspective
    ~20 ms for 230,400 pixels, loaded machine), so a smaller frame (a thumbnail stream) is cheaper
    per pixel than with one refill."""
    z = float(view.position[2])
    if z - (scene.ground.level if scene.ground.enabled else 0.0) > AERIAL_MAX_HEIGHT:
        return False
    return scene.camera.width * scene.camera.height >= math.prod(size)


def frame_aerial_table(frame, size=AERIAL_SIZE) -> dict | None:
    """The frame's table, filled (at most once per frame) and bound on its units; returns the
    uniforms a program reading it needs, or None where the table does not serve this view
    (table_serves: the caller then compiles AERIAL_EXACT). Sky-view and atmosphere tables are
    re-bound first: the fill samples them on their frame-wide units."""
    if not table_serves(frame.scene, frame.view, size):
        return None
    held = frame.resources.get("aerial_table")
    if held is None:
        table = AerialTable.get(frame.ctx, size)
        sky_view = frame.resources.get("sky_view")
        tables = frame.resources.get("atmosphere_tables")
        inputs = []
        if sky_view is not None:
            sky_view.bind()
            inputs.append(("sky_view", id(sky_view), sky_view.fills))
        if tables is not None:
            tables.bind()
            inputs.append(("tables", id(tables), tables.key))
        held_haze = held_haze_table(frame.ctx)  # the fog layer's light table and what it was made from
        inputs.append(("haze_table", None if held_haze is None else held_haze[1]))
        table.update(frame.uniforms, table_range(frame.scene, frame.view), tuple(inputs))
        held = frame.resources["aerial_table"] = table
    held.bind()
    return held.uniforms()
