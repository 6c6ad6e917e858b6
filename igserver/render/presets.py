"""Quality presets: ``low``, ``medium``, ``high`` map to every pipeline's knobs; ``auto`` picks
the highest level whose measured frame time fits a target, at run time (docs/design.md#quality).

Each pipeline registers its knobs per level (``register``), chosen from its error-vs-time curve in
``igserver quality`` (the report marks the points). A pass reads its knobs with
``knobs(name, frame.quality)``; ``frame.quality`` is the level in force for this frame (the scene's
``quality.preset``, or the auto controller's current rung).

Auto without popping: the controller does not jump between presets. It walks a ladder of rungs from
``low`` to ``high`` in which neighbouring rungs differ in ONE knob of ONE pipeline (``ladder``),
one rung per decision, with hysteresis (step down when the median frame time over a window exceeds
the target, step up only when it is below ``UP_FRACTION`` of it, and never twice within
``HOLD_FRAMES``); volume textures blend between models (volumes.py), so a changed knob fades in,
and a changed march resolution dissolves from the old to the new over a few frames (volumes.py).
"""

from __future__ import annotations

import statistics
from collections import deque
from dataclasses import dataclass, fields, is_dataclass, replace
from typing import Any

LEVELS = ("low", "medium", "high")

# pipeline -> level -> knobs (a frozen dataclass or a plain value)
_KNOBS: dict[str, dict[str, Any]] = {}


def register(pipeline: str, per_level: dict[str, Any]) -> None:
    """Declare a pipeline's knobs for each of ``LEVELS`` (done once, at import of the pipeline)."""
    missing = set(LEVELS) - set(per_level)
    if missing:
        raise ValueError(f"{pipeline}: knobs missing for {sorted(missing)}")
    _KNOBS[pipeline] = {level: per_level[level] for level in LEVELS}


def registered() -> dict[str, dict[str, Any]]:
    return {k: dict(v) for k, v in _KNOBS.items()}


@dataclass(frozen=True)
class Rung:
    """A point on the ladder: the knobs of every pipeline (a mix of two neighbouring levels)."""

    name: str  # e.g. "medium", or "low>medium volumes.steps"
    knobs: dict

    def __hash__(self) -> int:
        return hash(self.name)


def knobs(pipeline: str, quality: "str | Rung") -> Any:
    """The knobs of ``pipeline`` at a level name or a ladder rung."""
    if isinstance(quality, Rung):
        return quality.knobs[pipeline]
    return _KNOBS[pipeline][quality]


def _fields(value) -> list[str]:
    return [f.name for f in fields(value)] if is_dataclass(value) else []


def ladder() -> list[Rung]:
    """Rungs from ``low`` to ``high``; between two levels, one knob changes per rung.

    Knobs change in a fixed order per pipeline (the dataclass's field order), pipelines in
    registration order; a non-dataclass knob changes as a whole.
    """
    rungs = [Rung(LEVELS[0], {p: v[LEVELS[0]] for p, v in _KNOBS.items()})]
    for lo, hi in zip(LEVELS, LEVELS[1:]):
        start = len(rungs)
        current = dict(rungs[-1].knobs)
        for pipeline, per_level in _KNOBS.items():
            a, b = current[pipeline], per_level[hi]
            names = _fields(b)
            if names and type(a) is type(b):
                for name in names:
                    if getattr(a, name) != getattr(b, name):
                        a = replace(a, **{name: getattr(b, name)})
                        current = {**current, pipeline: a}
                        rungs.append(Rung(f"{lo}>{hi} {pipeline}.{name}", current))
            elif a != b:
                current = {**current, pipeline: b}
                rungs.append(Rung(f"{lo}>{hi} {pipeline}", current))
        if len(rungs) > start:
            rungs[-1] = Rung(hi, rungs[-1].knobs)  # the last rung of a stretch is the level itself
        else:
            rungs.append(Rung(hi, current))  # identical levels: a rung of its own all the same
    return rungs


WINDOW_FRAMES = 15  # frame times in the median a decision looks at
HOLD_FRAMES = 15  # frames after a change before the next one (the new rung's times fill the window)
UP_FRACTION = 0.75  # step up only below 75 % of the target: the next rung costs more


class AutoQuality:
    """The ``auto`` preset: one rung per decision, hysteresis, a hold time after each change."""

    def __init__(self, target_ms: float, start: str = "medium"):
        self.target_ms = target_ms
        self.rungs = ladder()
        names = [r.name for r in self.rungs]
        self.index = names.index(start) if start in names else 0
        self._times: deque[float] = deque(maxlen=WINDOW_FRAMES)
        self._hold = 0
        self.changes = 0

    @property
    def rung(self) -> Rung:
        return self.rungs[self.index]

    def observe(self, frame_ms: float) -> None:
        """Record one frame's time (render + readback) and maybe move one rung."""
        self._times.append(frame_ms)
        if self._hold > 0:
            self._hold -= 1
            return
        if len(self._times) < WINDOW_FRAMES:
            return
        median = statistics.median(self._times)
        if median > self.target_ms and self.index > 0:
            self._move(-1)
        elif median < UP_FRACTION * self.target_ms and self.index < len(self.rungs) - 1:
            self._move(+1)

    def _move(self, step: int) -> None:
        self.index += step
        self.changes += 1
        self._hold = HOLD_FRAMES
        self._times.clear()
