"""Handing freed heap back to the operating system (both the server and the render process use it)."""

from __future__ import annotations


def release_free_memory() -> None:
    """Give freed heap back to the OS (glibc ``malloc_trim``). After a big frame, glibc's dynamic mmap
    threshold has risen to the frame's size, so later frame-sized buffers come from the heap, and freed
    heap stays in the process: RSS would stay at the big frame's level. Called when the frame size changes."""
    try:
        import ctypes

        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):  # not glibc: nothing to do
        pass
