"""Frame readback through a ring of pixel-buffer objects, so reading frame N overlaps drawing frame N+1.

``Framebuffer.read`` waits for every queued draw of the frame and copies the pixels out before the
calling thread may go on. ``Framebuffer.read_into(buffer)`` with a GL buffer as the target (a pixel
pack buffer) only queues the copy: the driver does it after the frame's last draw, and the calling
thread returns to draw the next frame. The pixels are taken from the buffer one frame later, when
they are long done (on a GPU: no stall; on llvmpipe: the rasteriser threads finish the frame while
the calling thread sets up the next). A ring holds one buffer per frame in flight plus one being
written, so no buffer is read while the driver may still fill it.

Buffers are made once and re-made only when the frame grows: no GL object is created per frame.
"""

from __future__ import annotations

import moderngl
import numpy as np

from .channels import side_by_side


class ReadbackRing:
    """``slots`` pixel buffers, used in turn. ``start`` queues a framebuffer's copy into the next one;
    ``take`` returns that copy's pixels (RGBA8, top row first), waiting only if the copy is not done."""

    def __init__(self, ctx: moderngl.Context, slots: int = 2):
        if slots < 2:
            raise ValueError("a readback ring needs at least 2 buffers (one written while one is read)")
        self._ctx = ctx
        self._buffers: list[moderngl.Buffer | None] = [None] * slots
        self._next = 0

    @property
    def slots(self) -> int:
        return len(self._buffers)

    def start(self, fbo: moderngl.Framebuffer, size: tuple[int, int]) -> tuple[int, tuple[int, int]]:
        """Queue the copy of ``fbo``'s first colour attachment (``size`` = (width, height) pixels) into
        the next buffer of the ring; the returned ticket is what ``take`` needs."""
        if hasattr(fbo, "parts"):  # the channels of a frame (render/multiview.py ChannelGroup)
            return self.start_many(fbo.parts)
        slot = self._next
        self._next = (self._next + 1) % len(self._buffers)
        nbytes = size[0] * size[1] * 4
        buffer = self._buffers[slot]
        if buffer is None or buffer.size < nbytes:
            if buffer is not None:
                buffer.release()
            buffer = self._buffers[slot] = self._ctx.buffer(reserve=nbytes)
        fbo.read_into(buffer, components=4, alignment=1)
        return slot, size

    def start_many(self, parts: list) -> tuple[int, list[tuple[int, int]]]:
        """``start`` for several framebuffers ([(fbo, (width, height))]) into one buffer, one after the
        other (the channels of a frame); ``take_many`` returns their pixels."""
        slot = self._next
        self._next = (self._next + 1) % len(self._buffers)
        sizes = [size for _, size in parts]
        nbytes = sum(w * h * 4 for w, h in sizes)
        buffer = self._buffers[slot]
        if buffer is None or buffer.size < nbytes:
            if buffer is not None:
                buffer.release()
            buffer = self._buffers[slot] = self._ctx.buffer(reserve=nbytes)
        offset = 0
        for fbo, (w, h) in parts:
            fbo.read_into(buffer, components=4, alignment=1, write_offset=offset)
            offset += w * h * 4
        return slot, sizes

    def take_many(self, ticket: tuple[int, list[tuple[int, int]]]) -> list[np.ndarray]:
        """The pixels of each framebuffer of a ``start_many`` copy, top row first."""
        slot, sizes = ticket
        data = self._buffers[slot].read(size=sum(w * h * 4 for w, h in sizes))
        out, offset = [], 0
        for width, height in sizes:
            n = width * height * 4
            out.append(np.frombuffer(data, np.uint8, n, offset).reshape(height, width, 4)[::-1])
            offset += n
        return out

    def take(self, ticket: tuple[int, tuple[int, int]]) -> np.ndarray:
        """The pixels of a copy ``start`` queued: (height, width, 4) uint8, top row first (GL's rows
        run bottom-up). The caller must take a ticket before the ring comes round to its slot again."""
        if isinstance(ticket[1], list):  # start_many's: the channels side by side, as ChannelGroup reads them
            return side_by_side(self.take_many(ticket))
        slot, (width, height) = ticket
        data = self._buffers[slot].read(size=width * height * 4)
        rgba = np.frombuffer(data, dtype=np.uint8).reshape(height, width, 4)[::-1]
        return np.ascontiguousarray(rgba)

    def release(self) -> None:
        for buffer in self._buffers:
            if buffer is not None:
                buffer.release()
        self._buffers = [None] * len(self._buffers)
