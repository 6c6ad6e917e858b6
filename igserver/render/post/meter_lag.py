"""The exposure meter of a stream, one frame late, so no frame waits for its own meter.

Reading a frame's meter cells back (post.py ``meter_cells``) waits for every pass of the frame to
finish rasterising before the post pass can be queued: the calling thread cannot start the next
frame while this one is drawn (on a GPU: host and GPU serialised every frame; on llvmpipe: the
calling thread idles). In a continuous stream of one view (the eye adaptation's condition,
post/exposure.py: 0 < dt <= MAX_STREAM_DT in sim_time, the same view or the same channels) frame
N+1 is instead metered from frame N's cells, which a pixel-pack copy queued right after frame N's
meter dispatch (``MeterCopy``) brings out while frame N is drawn; they are read at frame N+1's post
pass or when frame N is collected, whichever comes first, when they are long done. The eye then
eases toward that target as before: the displayed exposure lags the light by one frame (33 ms at
30 Hz) against an adaptation of 0.4 s to 4 s.

A frame with no such predecessor (a single render, a stream's first frame, a jump in time, another
view, adaptation off, a fixed exposure, the cluster's shared exposure) meters its own cells at once,
exactly as it always did, and hands them on to its successor.
"""

from __future__ import annotations

import numpy as np

from .exposure import MAX_STREAM_DT


def finite_cells(raw: bytes, exposure: float) -> np.ndarray:
    """The finite cells (linear RGB before pre-exposure, float64 (N, 3)) of a meter texture's RGBA
    float32 data, the frame pre-exposed by ``exposure``."""
    cells = np.frombuffer(raw, dtype=np.float32).reshape(-1, 4)[:, :3].astype(np.float64)
    return cells[np.all(np.isfinite(cells), axis=1)] / max(exposure, 1e-30)


class MeterCopy:
    """A meter texture's asynchronous copy: a framebuffer on the texture and a pixel-pack buffer.
    ``queue`` only queues the copy (the driver does it after the meter's dispatch); ``generation``
    counts the copies, so a ticket knows when its data has been overwritten, and ``released`` when
    it is gone (a channel's copy, released with the channels while their last frame is in flight)."""

    def __init__(self, ctx, tex):
        self.tex = tex
        self.fbo = ctx.framebuffer(color_attachments=[tex])
        self.buffer = ctx.buffer(reserve=tex.width * tex.height * 16)
        self.generation = 0
        self.released = False

    def queue(self) -> int:
        self.fbo.read_into(self.buffer, components=4, dtype="f4", alignment=1)
        self.generation += 1
        return self.generation

    def release(self) -> None:
        self.fbo.release()
        self.buffer.release()
        self.released = True


def copy_for(held: MeterCopy | None, ctx, tex) -> MeterCopy:
    """``held`` when it copies ``tex``, else a new MeterCopy of ``tex`` (``held`` released): the
    caller keeps it with its meter texture."""
    if held is not None and held.tex is tex:
        return held
    if held is not None:
        held.release()
    return MeterCopy(ctx, tex)


class MeterTicket:
    """One frame's meter cells: read already (``cells`` given), or queued copies [(MeterCopy,
    generation, exposure)] read on the first ``cells()`` call (the channels' parts in order)."""

    def __init__(self, cells: np.ndarray | None = None, parts: list | None = None):
        self._cells, self._parts = cells, parts or []

    def cells(self) -> np.ndarray | None:
        """The cells; None when a copy was overwritten before it was read (its frame's state was
        dropped: the renderer's FrameState replaced) or released (its channels are gone: a frame of
        other views follows, which meters itself)."""
        if self._cells is None:
            out = []
            for copy, generation, exposure in self._parts:
                if copy.released or copy.generation != generation:
                    return None
                out.append(finite_cells(copy.buffer.read(), exposure))
            self._cells, self._parts = np.concatenate(out) if len(out) > 1 else out[0], []
        return self._cells


class MeterLag:
    """Kept in the renderer's FrameState: the last frame's meter ticket, its view key (None: a single
    view; the channels' ids) and sim_time."""

    def __init__(self):
        self.ticket: MeterTicket | None = None
        self.key = None
        self.sim_time: float | None = None

    def continues(self, key, scene, eye) -> bool:
        """Whether this frame may be metered from the last frame's cells: a continuous stream of
        the same view whose eye adapts (a cut, adaptation off, shows its own exposure)."""
        if self.ticket is None or not scene.camera.adaptation or eye.ev100 is None:
            return False
        if key != self.key or self.sim_time != eye.sim_time:
            return False
        return 0.0 < scene.time.sim_time - self.sim_time <= MAX_STREAM_DT

    def take(self) -> np.ndarray | None:
        """The last frame's cells (reads its copy if not read yet)."""
        return self.ticket.cells()

    def hold(self, ticket: MeterTicket, key, sim_time: float) -> None:
        """This frame's ticket, for its successor. The one it replaces is read first if it was not,
        so a frame still in flight can still find its cells."""
        self.clear()
        self.ticket, self.key, self.sim_time = ticket, key, sim_time

    def clear(self) -> None:
        """No successor may lag on the last frame (a fixed or shared exposure)."""
        if self.ticket is not None:
            self.ticket.cells()
        self.ticket = self.key = self.sim_time = None
