"""World work once per change: values derived from the world state, kept until their inputs change.

A stream that only advances ``sim_time`` asks every frame for the same instance rows, light list,
volume set, particle tiles...; recomputing them would be most of a frame's host time. Each such
item is computed through a ``Memo`` under a **key that names all of its inputs** (the entities,
the view's pose and frustum, the knobs, the model's identity, ...): an equal key returns the kept
value, any other key recomputes it. Nothing is invalidated by hand, so a stale value would need a
missing input in a key — which the tests look for by changing each input in turn.

``computed`` counts the recomputations per item, for those tests and for ``igserver bench``.
"""

from __future__ import annotations

from collections import Counter
from typing import Callable, Hashable, TypeVar

import numpy as np

T = TypeVar("T")


class Memo:
    """The last value of each named item with the key it was computed for."""

    # How many keys of each item are kept, the most recently used: set per frame by the renderer to
    # the number of views it draws. A frame of N channels (render/multiview.py) keeps each channel's
    # view-keyed items past the other channels' (a still eyepoint selects once per channel, not once
    # per channel per frame); 1 otherwise (the last frame's value).
    slots = 1

    def __init__(self):
        self._held: dict[str, tuple[Hashable, object]] = {}
        self._older: dict[str, list[tuple[Hashable, object]]] = {}  # up to slots - 1 earlier ones per item
        self.computed: Counter = Counter()

    def get(self, item: str, key: Hashable, compute: Callable[[], T]) -> T:
        held = self._held.get(item)
        if held is not None and held[0] == key:
            return held[1]
        older = self._older.setdefault(item, [])
        if held is not None and Memo.slots > 1:
            older.insert(0, held)
        hit = next((i for i, (k, _) in enumerate(older) if k == key), None)
        if hit is not None:
            self._held[item] = older.pop(hit)
            del older[Memo.slots - 1:]
            return self._held[item][1]
        del older[max(Memo.slots - 1, 0):]
        value = compute()
        self._held[item] = (key, value)
        self.computed[item] += 1
        return value

    def clear(self) -> None:
        self._held.clear()
        self._older.clear()


def view_key(view) -> tuple:
    """A camera view's pose, frustum and size, exactly (what view-dependent items are keyed on)."""
    return (view.position.tobytes(), view.rotation.tobytes(), view.projection.tobytes(), view.tangents,
            view.near, view.far, view.width, view.height)


def array_key(a) -> tuple:
    a = np.asarray(a)
    return (a.dtype.str, a.shape, a.tobytes())
