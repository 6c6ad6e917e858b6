"""Overload management: hold a frame rate by trading picture error for time.

An **operating point** (render/operating_points.py) is an internal render scale and a rung of the
presets' ladder, with an estimated error and a seed cost; the running IG's frame times turn the seed
into a prediction: ``predicted(p) = L * seed(p) * k(p)``. L (the load) is the median
of the last LOAD_WINDOW frames' observed ms over their point's seed and correction: it follows the
scene (a fire starting, the camera turning to the sea) whatever the point, in half a window, and a
lone slow frame (another process taking the cores) does not move it. k(p) corrects a point's seed: learned
on the frames just after a step UP to p, against the load measured just before it, so the ratio
of two points' costs is measured, not assumed. A step up follows UP_FRAMES steady frames, so that
load is a fresh reference; a step down follows a change of the load, so its frames update L, not
k (a ratio measured across a changing load would be wrong and stay wrong).

Only the **frontier** is used: the points no other point beats on both seed cost and error, sorted
from the cheapest (largest error) to the best. Per frame the controller (``Overload.observe``)

- steps **down at once** when DOWN_FRAMES frames in a row overran the frame budget 1/target: to
  the best frontier point whose predicted cost fits the budget less MARGIN (several points in one
  move if the load jumped: a sudden cost is absorbed in DOWN_FRAMES + 1 frames);
- steps **up** (a *probe*: the new point's cost is known only once its frames are seen) only after
  UP_FRAMES frames in a row with a better point predicted to fit in the budget less HEADROOM, and
  only while the recent frames leave room for it: the last P95_WINDOW frames' p95 plus the
  predicted extra cost of the new point must fit the budget less MARGIN. A probe's frames are the
  ones a viewer sees stutter, so the gate is on the tail of the frame times, not their median.
  A point never measured is predicted with the correction of the nearest measured point below it
  (the current point's measured ratio of true cost to seed, not the bare seed);
- moves up to the nearest such point (the next one on the frontier; a point past a blocked one
  only when its measured cost is below the blocked one's: the seed misordered them), or past it
  to the nearest better point at the current scale when that fits as well: changing the scale
  rebuilds every target at the move and again at a revert, a knob is the cheapest move to undo;
- a probe that overruns within PROBE_FRAMES of its step up *failed*: the controller goes back to
  the point it came from (its targets and knobs were just in use, its cost is measured), the load
  stays what it was (the overrun is the probed point's cost, now learned), and every further probe
  waits UP_FRAMES x 2^(failed probes in a row, at most MAX_PROBE_BACKOFF) steady frames, until a
  probe holds or the load falls clearly below the one the last probe failed under;
- steps **down one tail** when the frames held at a point keep a long tail: once P95_WINDOW frames
  have been drawn at it, a p95 over TAIL_LIMIT x the budget (the rate holds on the mean, but one
  frame in twenty stutters) moves to the best point predicted to fit with that tail: its predicted
  cost times the window's p95 over its prediction inside TAIL_LIMIT x the budget (the cheapest when
  none does).
  A lone spike never moves it; a machine whose frames spread does;
- after stepping down from a point, does not return to it for BLOCK_FRAMES x 2^(times it failed):
  a point that does not fit is not retried at a rate the eye would see as pumping. The block
  lifts early only when the load has fallen clearly below the one the point failed under.

A target the machine cannot reach leaves the cheapest point in force and ``met`` false: the frame
is as fast as the IG can make it, and says so. Nothing raises.

The time a frame costs is the render thread's cycle when frames are in flight (renderer.py
``collect``: drawing the next frame, then taking this one's pixels: the stream's rate), else the
frame's render and readback. The first WARMUP_FRAMES frames of a controller compile programs and
build targets: they measure nothing.
"""

from __future__ import annotations

import math
import statistics
from collections import deque
from dataclasses import dataclass

from . import presets
from .operating_points import PIPELINE_ERROR, SCALES, OperatingPoint, frontier, point_estimate

MARGIN = 0.10  # a point fits when predicted within 90 % of the budget (frame-time noise)
HEADROOM = 0.15  # step up only when frames take <= 85 % of the budget
DOWN_FRAMES = 2  # consecutive overruns before stepping down
UP_FRAMES = 30  # consecutive frames with headroom before stepping up (~1 s at 30 fps)
BLOCK_FRAMES = 120  # a point stepped down from waits this long (doubling per failure) before a retry
LOAD_WINDOW = 9  # frames in the load's median (a step in cost shows after 5; a lone spike never)
LEARN_FRAMES = 4  # frames after a move that measure the new point's cost ratio (the first is skipped)
LEARN_ALPHA = 0.5
WARMUP_FRAMES = 3  # a controller's first frames compile programs and build targets: no measure of load
P95_WINDOW = 60  # frames whose time spread gates a probe (~2 s at 30 fps: three a probe may add are 5 %)
TAIL_LIMIT = 1.1  # a held point's p95 frame time may exceed the budget by this factor (40 ms at 25 fps: 44 ms)
PROBE_FRAMES = 8  # an overrun this soon after a step up is the probed point's cost, not the scene's
MAX_BACKOFF = 5  # doublings at most of a point's block: 32 x BLOCK_FRAMES (~2.5 min at 25 fps)
MAX_PROBE_BACKOFF = 3  # doublings at most of the wait between probes: 8 x UP_FRAMES (~10 s at 25 fps)


@dataclass(frozen=True)
class Decision:
    """What a frame is rendered at, and what the controller expects of it (reported per frame)."""

    point: OperatingPoint
    target_fps: float
    met: bool  # the point's predicted cost fits the budget (false: the target is out of reach)
    predicted_ms: float

    def header(self) -> str:
        """The ``X-IG-Quality`` value (``quality_header``)."""
        return quality_header(self.fields())

    def fields(self) -> dict:
        """The report as a JSON object: what a frame carries (WebSocket messages, headers, /metrics)."""
        return {"scale": self.point.scale, "rungs": self.point.rungs, "error": round(self.point.error, 3),
                "target_fps": self.target_fps, "met": self.met, "predicted_ms": round(self.predicted_ms, 2)}


def quality_header(fields: dict) -> str:
    """``scale=0.75; rungs=volumes:medium,water:low; error=3.1; target=25; met=true`` from a frame's
    report (``Decision.fields``); error in 8-bit sRGB RMSE levels."""
    rungs = ",".join(f"{p}:{lv}" for p, lv in sorted(fields["rungs"].items()))
    return (f"scale={fields['scale']:g}; rungs={rungs}; error={fields['error']:.2f}; "
            f"target={fields['target_fps']:g}; met={'true' if fields['met'] else 'false'}")


class Overload:
    """The controller: one per renderer; ``decide`` before a frame, ``observe`` its time after."""

    def __init__(self, target_fps: float, pipelines: frozenset[str] = frozenset(PIPELINE_ERROR),
                 start: str = "medium", scales=SCALES, rungs: list | None = None):
        self.target_fps = target_fps
        self.scales, self.rungs = tuple(scales), rungs
        self.frame = 0  # frames observed
        self.load: float | None = None  # L: observed ms over the point's seed x correction
        self.correction: dict[tuple[float, str], float] = {}  # k(p), 1 until measured
        self.changes = 0
        self._over = self._spare = 0
        self._blocked: dict[tuple[float, str], int] = {}  # point -> frame it may be tried again
        self._strikes: dict[tuple[float, str], int] = {}
        self._since_move = 0
        self._load_before_move: float | None = None
        self._learning = False  # the frames after a step up measure the new point's k
        self._recent: list[float] = []  # normalised loads of the last DOWN_FRAMES frames
        self._block_load: dict[tuple[float, str], float] = {}  # point -> the load it failed under
        self._residuals: deque[float] = deque(maxlen=P95_WINDOW)  # frame ms less the point's prediction
        self._came_from: int | None = None  # the point a step up left (a failed probe returns to it)
        self._failed_probes = 0  # failed probes in a row (the probe wait doubles with each)
        self._failed_load = math.inf  # the load the last probe failed under
        self.probes = 0  # steps up taken
        self._norms: deque[float] = deque(maxlen=LOAD_WINDOW)  # the load's window
        self.pipelines = pipelines
        self.points = frontier(pipelines, self.scales, rungs)
        self.index = self._start(start)

    def _start(self, start: str) -> int:
        """The scale-1 point of the ``start`` rung, or the best frontier point not better than it."""
        names = [r.name for r in (self.rungs or presets.ladder())]
        ref = point_estimate(1.0, (self.rungs or presets.ladder())[names.index(start)] if start in names else
                             (self.rungs or presets.ladder())[0], self.pipelines)
        fitting = [i for i, p in enumerate(self.points) if p.error >= ref.error - 1e-9]
        return fitting[-1] if fitting else 0

    @property
    def budget_ms(self) -> float:
        return 1000.0 / self.target_fps

    @property
    def point(self) -> OperatingPoint:
        return self.points[self.index]

    def predicted_ms(self, i: int) -> float:
        return (self.load or 0.0) * self.points[i].seed_ms * self._k(i)

    def _k(self, i: int) -> float:
        """k(p): measured, else the nearest measured point's below it (the current point's when none
        is), else 1: a step's cost is the seed's difference on top of what the frames show."""
        key = self.points[i].key
        if key in self.correction:
            return self.correction[key]
        for j in range(i - 1, -1, -1):
            if self.points[j].key in self.correction:
                return self.correction[self.points[j].key]
        return self.correction.get(self.point.key, 1.0)

    def set_pipelines(self, pipelines: frozenset[str]) -> None:
        """The frame's drawn pipelines changed (a fire lit, the sea out of view): rebuild the frontier
        and keep the nearest point in error, the load and the corrections (per point, by key)."""
        if pipelines == self.pipelines:
            return
        error = self.point.error
        self.pipelines = pipelines
        self.points = frontier(pipelines, self.scales, self.rungs)
        self.index = min(range(len(self.points)), key=lambda i: abs(self.points[i].error - error))

    def decision(self) -> Decision:
        predicted = self.predicted_ms(self.index)
        return Decision(self.point, self.target_fps, self.load is None or predicted <= self.budget_ms, predicted)

    def observe(self, frame_ms: float) -> None:
        """One frame's time at the current point; maybe move (down at once, up one point)."""
        self.frame += 1
        if self.frame <= WARMUP_FRAMES:
            return
        point = self.point
        norm = frame_ms / (point.seed_ms * self._k(self.index))
        self._since_move += 1
        if self._learning and 1 < self._since_move <= LEARN_FRAMES:
            # the cost ratio of this point to the load measured just before the move
            k = frame_ms / (self._load_before_move * point.seed_ms)
            old = self._k(self.index)
            self.correction[point.key] = old + LEARN_ALPHA * (k - old)
        elif self._since_move > 1 or self.load is None:  # a move's first frame builds targets: not load
            self._norms.append(norm)
            self.load = statistics.median(self._norms)
        self._recent = (self._recent + [norm])[-DOWN_FRAMES:]
        if self._since_move > 1 and self.load is not None:
            self._residuals.append(frame_ms - self.predicted_ms(self.index))
        budget = self.budget_ms
        # a move's first frame (new targets, new programs) is not an overrun of the point
        self._over = self._over + 1 if frame_ms > budget and self._since_move > 1 else 0
        up = self._up_candidate()
        self._spare = self._spare + 1 if up is not None else 0
        if self._came_from is not None and self._since_move > PROBE_FRAMES:
            self._came_from, self._failed_probes = None, 0  # the probe held: it fits
        if self.load is not None and self.load < (1.0 - HEADROOM) * self._failed_load:
            self._failed_probes, self._failed_load = 0, math.inf  # the scene got cheaper: probe again
        if self._over >= DOWN_FRAMES and self.index > 0:
            self._step_down()
        elif self._tail_too_long() and self.index > 0:
            self._tail_down()
        elif self._spare >= UP_FRAMES * 2 ** min(self._failed_probes, MAX_PROBE_BACKOFF) and self._probe_fits(up):
            self.probes += 1
            self._move(self._same_scale(up))

    def _step_down(self) -> None:
        if self._came_from is not None and self._load_before_move is not None:
            # A failed probe: the overrun is the probed point's cost (its k, learned from these very
            # frames), not the scene's, so the load stays what it was before the step up. Back where
            # it came from: just drawn (no new targets or knobs), its cost measured.
            self._failed_probes += 1
            self.load = self._failed_load = self._load_before_move
            target = self._came_from
        else:
            # The overrunning frames are the load now (the median lags a step in cost by half its
            # window): it holds the window's median until the new point's frames outnumber it.
            self.load = max(self.load or 0.0, min(self._recent))
            self._norms.clear()
            self._norms.extend([self.load] * (LOAD_WINDOW // 2 + 1))
            fit = (1.0 - MARGIN) * self.budget_ms
            fitting = [i for i in range(self.index) if self.predicted_ms(i) <= fit]
            target = fitting[-1] if fitting else 0  # nothing fits: the cheapest point, target not met
        key = self.point.key
        strikes = self._strikes.get(key, 0)
        self._blocked[key] = self.frame + BLOCK_FRAMES * 2 ** min(strikes, MAX_BACKOFF)
        self._block_load[key] = self.load
        self._strikes[key] = strikes + 1
        self._move(target)

    def _tail(self) -> float:
        """The p95 of the recent frames' time over their point's prediction (ms; 0 when they fit it)."""
        return max(sorted(self._residuals)[int(0.95 * (len(self._residuals) - 1))], 0.0)

    def _tail_too_long(self) -> bool:
        """P95_WINDOW frames drawn at this point since the last move (the residuals window holds only them) and their
        p95 over TAIL_LIMIT x the budget."""
        if len(self._residuals) < P95_WINDOW or self._since_move <= P95_WINDOW:
            return False
        return self.predicted_ms(self.index) + self._tail() > TAIL_LIMIT * self.budget_ms

    def _tail_down(self) -> None:
        """Down to the best point predicted to fit with the tail the frames show (see the module)."""
        # the tail as a ratio to the point's cost: the slow frames are the same work made slower
        here = max(self.predicted_ms(self.index), 1e-9)
        spread, limit = (here + self._tail()) / here, TAIL_LIMIT * self.budget_ms
        fitting = [i for i in range(self.index) if self.predicted_ms(i) * spread <= limit]
        key = self.point.key
        strikes = self._strikes.get(key, 0)
        self._blocked[key] = self.frame + BLOCK_FRAMES * 2 ** min(strikes, MAX_BACKOFF)
        self._block_load[key] = self.load
        self._strikes[key] = strikes + 1
        self._came_from = None
        self._move(fitting[-1] if fitting else 0)

    def _is_blocked(self, j: int) -> bool:
        key = self.points[j].key
        if self._blocked.get(key, 0) <= self.frame:
            return False
        # the load it failed under has fallen clearly (the scene got cheaper): it may fit now
        return (self.load or 0.0) > (1.0 - HEADROOM) * self._block_load.get(key, math.inf)

    def _up_candidate(self) -> int | None:
        """The nearest better point, not blocked, predicted within the budget less HEADROOM. Past a
        blocked point only to one whose measured cost is below the blocked one's: a point costlier
        than one that just failed would fail too."""
        fit = (1.0 - HEADROOM) * self.budget_ms
        ceiling = math.inf
        for j in range(self.index + 1, len(self.points)):
            predicted = self.predicted_ms(j)
            if self._is_blocked(j):
                ceiling = min(ceiling, predicted)
                continue
            if predicted <= fit and (ceiling == math.inf or
                                     (self.points[j].key in self.correction and predicted < ceiling)):
                return j
        return None

    def _same_scale(self, up: int) -> int:
        """``up``, or when it changes the internal scale, the nearest better point at the current
        scale if it fits as well: a scale change rebuilds every target at the move and again at a
        revert, a knob at the same scale is the cheapest move to undo. Its error is lower still, so
        no least-error point is passed over."""
        if self.points[up].scale == self.point.scale:
            return up
        fit = (1.0 - HEADROOM) * self.budget_ms
        for j in range(up + 1, len(self.points)):
            if self._is_blocked(j):
                return up  # past a point that failed: only the measured nearest candidate
            if self.points[j].scale == self.point.scale:
                return j if self.predicted_ms(j) <= fit and self._probe_fits(j) else up
        return up

    def _probe_fits(self, j: int | None) -> bool:
        """The probe's frames are predicted inside the budget less MARGIN at their p95: the recent
        frames' spread over their prediction added to the new point's predicted cost."""
        if j is None:
            return False
        if len(self._residuals) < min(UP_FRAMES, P95_WINDOW):
            return False  # too few frames to know the tail yet
        tail = sorted(self._residuals)[int(0.95 * (len(self._residuals) - 1))]
        return self.predicted_ms(j) + max(tail, 0.0) <= (1.0 - MARGIN) * self.budget_ms

    def _move(self, index: int) -> None:
        if index == self.index:
            return
        self._load_before_move = self.load
        self._learning = index > self.index and self.load is not None
        self._came_from = self.index if index > self.index else None
        self.index = index
        self.changes += 1
        self._since_move = 0
        self._over = self._spare = 0
        self._recent = []


def scene_target_fps(quality) -> float:
    """The frame rate a scene's ``quality`` asks the controller to hold; 0 = no controller. ``auto``
    without a ``target_fps`` holds ``target_ms``."""
    if quality.target_fps > 0.0:
        return float(quality.target_fps)
    return 1000.0 / quality.target_ms if quality.preset == "auto" else 0.0


class FrameQuality:
    """The renderer's controller: made when a scene asks for one (``scene_target_fps``), kept while
    the target and preset stay; ``auto`` moves every pipeline's rung and the scale, a fixed preset
    only the scale. ``decide`` gives a frame's point, ``observe`` takes its time. With no target the
    frame's point is the scene's preset at the renderer's scale, reported with target 0 (met)."""

    def __init__(self) -> None:
        self.controller: Overload | None = None
        self._key: tuple[float, str] | None = None
        self._pipelines: frozenset[str] = frozenset(PIPELINE_ERROR)
        self._fixed: dict[tuple, Decision] = {}  # the no-target reports, per (preset, scale, pipelines)

    def decide(self, scene, scale: float = 1.0) -> Decision:
        target = scene_target_fps(scene.quality)
        preset = scene.quality.preset
        if target <= 0.0:
            self.controller, self._key = None, None
            return self._fixed_decision(preset, scale)
        if (target, preset) != self._key:
            rungs = None if preset == "auto" else [r for r in presets.ladder() if r.name == preset]
            self.controller = Overload(target, self._pipelines, start=preset if preset != "auto" else "medium",
                                       rungs=rungs)
            self._key = (target, preset)
        return self.controller.decision()

    def _fixed_decision(self, preset: str, scale: float) -> Decision:
        key = (preset, scale, self._pipelines)
        if key not in self._fixed:
            rung = next(r for r in presets.ladder() if r.name == preset)
            self._fixed[key] = Decision(point_estimate(scale, rung, self._pipelines), 0.0, True, 0.0)
        return self._fixed[key]

    def observe(self, frame_ms: float, passes: list[str]) -> None:
        """The frame's time and the passes it drew (the pipelines whose knobs cost and err)."""
        self._pipelines = frozenset(p for p in passes if p in PIPELINE_ERROR)
        if self.controller is not None:
            self.controller.set_pipelines(self._pipelines)
            self.controller.observe(frame_ms)
