"""Quality presets: ``low``, ``medium``, ``high`` map to every pipeline's knobs; ``auto`` lets the
overload controller (render/overload.py) choose the knobs and the render scale per frame to hold a
frame rate (docs/design.md#quality).

Each pipeline registers its knobs per level (``register``), chosen from its error-vs-time curve in
``igserver quality`` (the report marks the points). A pass reads its knobs with
``knobs(name, frame.quality)``; ``frame.quality`` is the level in force for this frame (the scene's
``quality.preset``, or the controller's current rung).

No popping: the controller moves along a ladder of rungs from ``low`` to ``high`` in which
neighbouring rungs differ in ONE knob of ONE pipeline (``ladder``), with hysteresis; volume
textures blend between models (volumes/modelling.py), so a changed knob fades in, and a changed march
resolution dissolves from the old to the new over a few frames (volumes/volumes.py).
"""

from __future__ import annotations

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
    # Pipelines in name order, whatever order their modules were imported in: the ladder's rungs (and
    # so the overload controller's operating points) are the same in every process.
    ordered = dict(sorted(_KNOBS.items()))
    _KNOBS.clear()
    _KNOBS.update(ordered)


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

    Knobs change in a fixed order per pipeline (the dataclass's field order), pipelines in name
    order; a non-dataclass knob changes as a whole.
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
