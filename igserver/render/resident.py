"""One resident object per GL context, kept between frames (the per-frame tables a pass refills
only when what they hold changed: render/sky/sky_view.py, render/common/aerial_table.py)."""

from __future__ import annotations

from typing import TypeVar

import moderngl

T = TypeVar("T")


def resident(cls: type[T], ctx: moderngl.Context, size) -> T:
    """``cls``'s instance for ``ctx``, held in ``cls._resident`` (a WeakKeyDictionary: it goes with
    the context); made anew, the old one released, when there is none or it has another size."""
    held = cls._resident.get(ctx)
    if held is None or held.size != tuple(size):
        if held is not None:
            held.release()
        held = cls(ctx, size)
        cls._resident[ctx] = held
    return held
