"""The beach's swash (water/shore.glsl): run-up from the offshore waves, the swash's cadence and its
along-shore phase, and the plane of a slope beach."""

from __future__ import annotations

import math

import numpy as np

from ...scene.model import Scene
from ...water.bathymetry import _unit
from ...water.land import LAND_PERIOD
from ...water.surface import SeaSurface
from ..camera import CameraView

G = 9.80665
MAP_BEACH_SLOPE = 0.05  # foreshore slope assumed on a height map (its contours are not analysed)
RUNUP_VARIATION_LENGTH = 120.0  # m: along-shore scale of the run-up's variation (beach cusps, wave groups)
TWO_PI = 2.0 * math.pi


def runup_r2(h0: float, tp: float, beta: float) -> float:
    """Vertical run-up exceeded by 2 % of the waves (m), Stockdon et al. (2006) eq. 19:
    R2 = 1.1 (0.35 β (H0 L0)^½ + ½ (H0 L0 (0.563 β² + 0.004))^½), H0 the deep-water significant
    height (m), L0 = g Tp² / 2π the deep-water wavelength of the peak period Tp (s), β the foreshore
    slope; both setup and swash."""
    hl = max(h0, 0.0) * G * tp * tp / TWO_PI
    return 1.1 * (0.35 * beta * math.sqrt(hl) + 0.5 * math.sqrt(hl * (0.563 * beta * beta + 0.004)))


def dominant_waves(scene: Scene, sea: SeaSurface) -> tuple[float, float, np.ndarray]:
    """(H0 m, Tp s, unit direction the dominant waves travel to): the swell or the wind sea, whichever
    peaks higher in the combined spectrum (energy H² times period: a narrow swell peak stands above a
    broader wind sea of the same energy); H0 the two combined."""
    swell = scene.ocean.swell
    hs = sea.spectrum.hs
    h0 = math.hypot(hs, swell.height)
    tp_sea = TWO_PI / max(sea.spectrum.omega_p, 1e-6)
    if swell.height ** 2 * swell.period >= hs ** 2 * tp_sea:
        return h0, swell.period, _unit(swell.direction + 180.0)
    return h0, tp_sea, _unit(sea.spectrum.azimuth_to)


def shore_uniforms(scene: Scene, view: CameraView, sea: SeaSurface) -> dict:
    """The swash's uniforms for the frame (zeros where there is no bathymetry field: no shore)."""
    bathy = scene.ocean.bathymetry
    if sea.field is None or bathy.type == "uniform":
        return {"u_shore_plane": (1.0, 0.0, 0.0, 0.0), "u_swash": (0.0, 0.0, 0.0, 0.0),
                "u_swash_along": (0.0, 1.0, 0.0, 0.0), "u_land": (0.0, 0.0, 0.0, 0.0)}
    cam = np.asarray(view.position[:2], dtype=np.float64)
    if bathy.type == "slope":
        to_shore = _unit(bathy.shore_heading)
        beta = bathy.slope
        plane = (*to_shore, bathy.shore_distance - float(cam @ to_shore), beta)
    else:  # a height map: the land's height is the field's -depth; its shore direction is not known
        to_shore = _unit(bathy.map_heading)
        beta = MAP_BEACH_SLOPE
        plane = (*to_shore, 0.0, 0.0)
    along = np.array([to_shore[1], -to_shore[0]])
    h0, tp, direction = dominant_waves(scene, sea)
    omega = TWO_PI / tp
    # Along parallel contours the waves keep their along-shore wavenumber (Snell's law for refraction):
    # k_y = k0 sin(theta0), k0 = omega^2 / g the deep-water wavenumber.
    k_y = omega * omega / G * float(direction @ along) if bathy.type == "slope" else 0.0
    y_cam = float(cam @ along)
    phase = math.fmod(omega * scene.time.sim_time - k_y * y_cam, TWO_PI) % TWO_PI
    k_var = TWO_PI / RUNUP_VARIATION_LENGTH
    return {"u_shore_plane": tuple(float(x) for x in plane),
            "u_swash": (runup_r2(h0, tp, beta), phase, k_y, 0.0),
            "u_swash_along": (*(float(x) for x in along), k_var, math.fmod(k_var * y_cam, TWO_PI)),
            # the land behind a slope beach (water/land.py): its along-shore variation wraps on LAND_PERIOD
            "u_land": ((bathy.berm_height, bathy.dune_height, y_cam % LAND_PERIOD, 1.0) if bathy.type == "slope"
                       else (0.0, 0.0, 0.0, 0.0))}


# m: water.frag.glsl draws the swash and the land where the rest point stands above this (shore_elevation).
LAND_DRAWN_ABOVE = -0.05
LAND_MARGIN = 0.05  # m: against float32's rounding of the shader's plane (metres to kilometres from the eye)


def blocks_reaching_land(nodes: np.ndarray, scene: Scene, view: CameraView, sea: SeaSurface) -> np.ndarray:
    """Per LOD block (rows x, y of its corner, side: camera-relative m), whether some rest point in it
    stands above LAND_DRAWN_ABOVE, less LAND_MARGIN: only those blocks are drawn by the program with
    the swash and the land (water.frag.glsl WATER_LAND), which costs a beach's water pass a quarter
    on llvmpipe, where a fragment shader runs every branch on every pixel. Elsewhere those lines
    leave the sea's colour as it is. A fragment's rest point lies in its block's square (vertices are
    morphed within it), so the extreme corner bounds a slope beach's plane, and the corners' grid
    cells bound a height map's depth (bilinear between nodes, clamped at the grid's edge)."""
    bathy = scene.ocean.bathymetry
    if sea.field is None or bathy.type == "uniform" or len(nodes) == 0:
        return np.zeros(len(nodes), dtype=bool)
    corners = nodes[:, None, 0:2] + nodes[:, None, 2:3] * np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
    floor = LAND_DRAWN_ABOVE - LAND_MARGIN
    if bathy.type == "slope":
        plane = shore_uniforms(scene, view, sea)["u_shore_plane"]
        reach = np.max(corners @ np.array(plane[0:2]), axis=1)
        return plane[3] * (reach - plane[2]) > floor
    grid, depth = sea.field.grid, sea.field.depth
    gu, gv = grid.to_grid(corners + np.asarray(view.position[:2], dtype=np.float64))
    lo_u, hi_u = np.floor(gu.min(axis=1)).astype(int), np.ceil(gu.max(axis=1)).astype(int)
    lo_v, hi_v = np.floor(gv.min(axis=1)).astype(int), np.ceil(gv.max(axis=1)).astype(int)
    return np.array([-float(depth[a:b + 1, c:d + 1].min()) > floor
                     for a, b, c, d in zip(lo_u, hi_u, lo_v, hi_v)], dtype=bool)
