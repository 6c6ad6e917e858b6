"""Operating points: what a frame may be drawn at, and what each costs and shows.

An **operating point** is an internal render scale (render/scaling.py) and a rung of the presets'
ladder (render/presets.py: every pipeline's knobs, one knob changing between neighbouring rungs).
Each point has

- an **estimated error**, e (8-bit sRGB RMSE over the frame): the pipelines' errors at their
  knobs, from the error-against-time studies (docs/quality-report.md, as the table ``PIPELINE_ERROR``
  below), each weighted by the share of the frame that pipeline typically covers, and the scale's
  measured upscale error (docs/quality.md, ``SCALE_ERROR``), added as independent errors:
  ``e^2 = sum_p w_p e_p^2 + e_scale^2``;
- an **estimated cost**, ms per frame: a seed from the same studies (each pipeline's ms at its
  knobs, a fixed share of the frame's time that does not shrink with the pixels, the rest ~ scale^2)
  the controller turns into a prediction with the frame times the running IG sees.

Only the frontier is used (``frontier``: the points no other beats on both seed cost and error); the
controller that chooses among them per frame is render/overload.py.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, is_dataclass

from . import presets

SCALES = (1.0, 0.85, 0.75, 0.67, 0.5)  # the internal render scales (render/scaling.py), best first

# The error-against-time studies' preset points (docs/quality-report.md): error (8-bit sRGB RMSE of
# the pipeline's pixels against its reference) and ms (the pipeline's pass at the study's size).
PIPELINE_ERROR = {  # pipeline -> level -> (error, ms)
    "volumes": {"low": (15.1, 7.42), "medium": (12.7, 20.5), "high": (6.36, 123.0)},
    "water": {"low": (3.91, 24.2), "medium": (1.27, 36.9), "high": (1.18, 38.8)},
    "precip": {"low": (2.6, 12.3), "medium": (2.15, 20.6), "high": (1.69, 36.7)},
}
# Share of a frame's pixels each pipeline typically covers (its error spreads over those only): the
# sea fills the half below the horizon, a fire's plume a tenth, rain and snow the whole frame.
COVERAGE = {"volumes": 0.1, "water": 0.5, "precip": 1.0}
# The upscale's error against the full-resolution frame, 8-bit RMSE = 255 * 10^(-PSNR/20), from the
# demo at 640x360 (docs/quality.md, Internal render scale).
SCALE_ERROR = {1.0: 0.0, 0.85: 2.64, 0.75: 3.08, 0.67: 4.13, 0.5: 4.66}
BASE_MS = 25.0  # ms, the rest of a frame at 640x360 (sky, surfaces, post, readback), seed only
HOST_SHARE = 0.25  # of a frame's time that does not shrink with the pixels (demo: 0.5 scale = 0.42 x time)


def level_of(pipeline: str, value) -> str:
    """A pipeline's knobs as a level name: "low", "medium", "high", or "low>medium" between two."""
    table = presets.registered()[pipeline]
    for level in presets.LEVELS:
        if table[level] == value:
            return level
    lo, hi = _between(pipeline, value)
    return f"{lo}>{hi}"


def _between(pipeline: str, value) -> tuple[str, str]:
    """The two neighbouring levels whose knobs ``value`` mixes (the ladder changes one field at a time)."""
    table = presets.registered()[pipeline]
    for lo, hi in zip(presets.LEVELS, presets.LEVELS[1:]):
        a, b = table[lo], table[hi]
        if is_dataclass(value) and type(value) is type(a) and all(
                getattr(value, f.name) in (getattr(a, f.name), getattr(b, f.name)) for f in fields(value)):
            return lo, hi
    return presets.LEVELS[0], presets.LEVELS[-1]


def _progress(pipeline: str, value) -> tuple[str, str, float]:
    """(lo, hi, t): ``value`` lies a fraction t of the knobs (those that differ) from lo to hi."""
    table = presets.registered()[pipeline]
    level = level_of(pipeline, value)
    if level in presets.LEVELS:
        return level, level, 0.0
    lo, hi = _between(pipeline, value)
    a, b = table[lo], table[hi]
    differ = [f.name for f in fields(a) if getattr(a, f.name) != getattr(b, f.name)]
    moved = sum(getattr(value, n) == getattr(b, n) for n in differ)
    return lo, hi, moved / max(len(differ), 1)


def pipeline_error_ms(pipeline: str, value) -> tuple[float, float]:
    """(error, ms) of a pipeline at its knobs: the studies' preset points, linear between levels by
    the share of the knobs that moved (the ladder's intermediate rungs)."""
    if pipeline not in PIPELINE_ERROR:
        return 0.0, 0.0
    lo, hi, t = _progress(pipeline, value)
    (e0, m0), (e1, m1) = PIPELINE_ERROR[pipeline][lo], PIPELINE_ERROR[pipeline][hi]
    return e0 + t * (e1 - e0), m0 + t * (m1 - m0)


@dataclass(frozen=True)
class OperatingPoint:
    scale: float
    rung: presets.Rung
    error: float  # estimated frame error, 8-bit RMSE
    seed_ms: float  # seed cost (the studies' ms), before the learned load and correction

    @property
    def rungs(self) -> dict[str, str]:
        """Each pipeline's level at this point (e.g. {"water": "low", "volumes": "medium"})."""
        return {p: level_of(p, v) for p, v in self.rung.knobs.items()}

    @property
    def key(self) -> tuple[float, str]:
        return self.scale, self.rung.name


def point_estimate(scale: float, rung: presets.Rung, pipelines: frozenset[str]) -> OperatingPoint:
    """The point's estimated error and seed cost, counting only the ``pipelines`` this frame draws."""
    err2, ms = SCALE_ERROR.get(scale, 0.0) ** 2, BASE_MS
    for pipeline, value in rung.knobs.items():
        if pipeline in pipelines:
            e, m = pipeline_error_ms(pipeline, value)
            err2 += COVERAGE.get(pipeline, 1.0) * e * e
            ms += m
    return OperatingPoint(scale, rung, math.sqrt(err2), ms * (HOST_SHARE + (1.0 - HOST_SHARE) * scale * scale))


def frontier(pipelines: frozenset[str], scales=SCALES, rungs=None) -> list[OperatingPoint]:
    """The points no other beats on both seed cost and error, cheapest (largest error) first."""
    points = [point_estimate(s, r, pipelines) for s in scales for r in (rungs or presets.ladder())]
    points.sort(key=lambda p: (p.seed_ms, p.error))
    out: list[OperatingPoint] = []
    for p in points:
        if not out or p.error < out[-1].error - 1e-9:
            out.append(p)
    return out
