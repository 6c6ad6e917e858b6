"""Scratch arrays for the sea surface's evaluations and queries, reused from call to call.

A query works on arrays of points x waves; allocating them afresh each call costs more than the
arithmetic on them, so they are kept by name and handed out one workspace per concurrent query.
"""

from __future__ import annotations

import math
import threading
from contextlib import contextmanager

import numpy as np


class _Work:
    """Reusable scratch arrays by name: a query allocates nothing of size points x waves once warm (fresh
    pages cost more than the arithmetic on this kind of machine)."""

    def __init__(self):
        self.buffers: dict[str, np.ndarray] = {}

    def get(self, name: str, shape: tuple, dtype=np.float64) -> np.ndarray:
        size = math.prod(shape)
        b = self.buffers.get(name)
        if b is None or b.size < size or b.dtype != dtype:
            b = self.buffers[name] = np.empty(size, dtype)
        return b[:size].reshape(shape)


_WORKSPACES: list[_Work] = []
_WORKSPACES_LOCK = threading.Lock()


@contextmanager
def _workspace():
    """A scratch workspace for one query (queries run concurrently on the server's threads)."""
    with _WORKSPACES_LOCK:
        w = _WORKSPACES.pop() if _WORKSPACES else _Work()
    try:
        yield w
    finally:
        with _WORKSPACES_LOCK:
            if len(_WORKSPACES) < 4:
                _WORKSPACES.append(w)
