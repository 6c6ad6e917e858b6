"""The foam the water shader draws: coverage from the surface's Jacobian against a threshold chosen so
the drawn whitecap fraction follows the measured one, dithered into wind streaks by a tabulated noise."""

from __future__ import annotations

import math

import numpy as np

from ...scene.model import Scene
from ...water.surface import SeaSurface, whitecap_coverage
from ..bindings import FRAME_UNITS
from ..camera import CameraView

# The foam water.frag.glsl draws: a fraction f rising from 0 at J = threshold + FOAM_EDGE[0] to 1 at
# threshold − FOAM_EDGE[1] (smoothstep), dithered into streaks by noise through a ramp of width
# FOAM_SOFT (its mean over the noise: foam_mean).
FOAM_EDGE = (0.02, 0.06)
FOAM_SOFT = 0.25


def foam_mean(f: np.ndarray) -> np.ndarray:
    """The drawn foam's mean over the dither noise (u uniform on [0, 1]) at foam fraction f:
    E[clamp((f − (1 − w) u) / w, 0, 1)], w = FOAM_SOFT, in closed form (water.frag.glsl foam_mean)."""
    w = FOAM_SOFT
    covered = np.where(f < w, f * f / (2.0 * w), np.where(
        f <= 1.0 - w, f - 0.5 * w, (f - w) + (w * w - (f - 1.0 + w) ** 2) / (2.0 * w)))
    return covered / (1.0 - w)


FOAM_STREAK_SIZE = (24.0, 3.0)  # m along and across the wind: a noise cell of the streaks
FOAM_STREAK_FADE = 0.75  # cells a pixel spans where the streaks have faded to their mean (water.frag.glsl)
FOAM_DRIFT = 0.03  # × wind speed: the surface drift that carries the streaks downwind
FOAM_PERIOD = 64.0  # noise cells per side of the tabulated noise: 1.5 km along the wind, 192 m across
FOAM_NOISE_SIZE = 256  # texels per side: 4 per noise cell (bilinear; the shader fades the streaks before it minifies)
FOAM_NOISE_UNIT = FRAME_UNITS["FOAM_NOISE"]


def foam_frame(scene: Scene, view: CameraView) -> dict:
    """The streak noise's frame (water.frag.glsl foam_cover): downwind axis and cell sizes, and the
    camera's noise coordinates, drifted downwind by the time, reduced mod the period in float64 so
    the streaks stay put on the sea at any distance from the origin and any sim_time."""
    to = math.radians(scene.weather.wind_direction + 180.0)  # the wind blows from wind_direction
    axis = np.array([math.sin(to), math.cos(to)])
    across = np.array([-axis[1], axis[0]])
    cam = np.asarray(view.position[:2], dtype=np.float64)
    drift = FOAM_DRIFT * scene.weather.wind_speed * scene.time.sim_time  # m downwind
    offset = np.mod([(float(cam @ axis) - drift) / FOAM_STREAK_SIZE[0], float(cam @ across) / FOAM_STREAK_SIZE[1]],
                    FOAM_PERIOD)
    return {"u_foam_frame": (*axis, 1.0 / FOAM_STREAK_SIZE[0], 1.0 / FOAM_STREAK_SIZE[1]),
            "u_foam_offset": tuple(float(x) for x in offset), "u_foam_period": FOAM_PERIOD,
            "u_foam_noise": FOAM_NOISE_UNIT}


_FOAM_CACHE: dict[tuple, tuple[SeaSurface, float]] = {}


def drawn_foam_threshold(sea: SeaSurface, wind: float) -> float:
    """The J threshold at which the foam the shader draws covers Monahan's whitecap fraction W of the
    sea on average. Its soft edge and its dither thin the foam out, so the threshold is set on the
    drawn foam's mean (``foam_mean``) over the sea's J samples — weighted by J, the displaced area each
    rest point stands for — not on the J quantile at W (which, softened and then halved by the old
    streak texture, drew foam over 3 % of the sea at Beaufort 9 instead of W = 16 %, and 0.02 % at
    Beaufort 5 instead of 0.8 %)."""
    key = id(sea), float(wind)
    held = _FOAM_CACHE.get(key)
    if held is not None and held[0] is sea:  # the sea is held with it: its id cannot be reused meanwhile
        return held[1]
    if len(_FOAM_CACHE) > 16:
        _FOAM_CACHE.clear()
    coverage = whitecap_coverage(wind)
    threshold = -1.0
    if coverage > 0.0 and sea.n > 0:
        j = sea.jacobian_samples
        area = np.maximum(j, 0.0)
        edge = FOAM_EDGE[0] + FOAM_EDGE[1]

        def drawn(t: float) -> float:
            x = np.clip((t + FOAM_EDGE[0] - j) / edge, 0.0, 1.0)
            return float(np.average(foam_mean(x * x * (3.0 - 2.0 * x)), weights=area))

        lo, hi = float(j.min()) - FOAM_EDGE[0], float(j.max()) + FOAM_EDGE[1]  # drawn 0 .. 1
        for _ in range(40):  # bisection: the drawn mean rises with the threshold
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if drawn(mid) < coverage else (lo, mid)
        threshold = 0.5 * (lo + hi)
    _FOAM_CACHE[key] = (sea, threshold)
    return threshold
