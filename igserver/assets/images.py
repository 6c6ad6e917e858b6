"""Image assets checked from their header at validation: a state naming an image that cannot be used is
refused (422) when it is sent, never failed at render time.

A PNG's size is in its first chunk (IHDR): a 24 KB file can announce 20000 x 10000 pixels (a decompression
bomb: gigabytes once decoded). The header is read here, without decoding, and the pixel count bounded by
``max_profile_pixels`` (a server setting; ``IGSERVER_MAX_PROFILE_PIXELS`` in the environment).
"""

from __future__ import annotations

import os
import struct
from functools import lru_cache
from pathlib import Path

DEFAULT_MAX_PROFILE_PIXELS = 1024 * 1024  # a profile is resampled to 128 x 64 texels: more only costs time
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"

_limit: int | None = None


def set_profile_pixel_limit(pixels: int | None) -> None:
    """The server's ``max_profile_pixels`` (None: the environment's, else the default)."""
    global _limit
    _limit = pixels


def profile_pixel_limit() -> int:
    if _limit is not None:
        return _limit
    try:
        return int(os.environ.get("IGSERVER_MAX_PROFILE_PIXELS", DEFAULT_MAX_PROFILE_PIXELS))
    except ValueError:
        return DEFAULT_MAX_PROFILE_PIXELS


class ImageError(ValueError):
    """An image asset that cannot be used; the message names no server path."""


@lru_cache(maxsize=64)
def _png_size(path: str, mtime_ns: int, size: int) -> tuple[int, int]:
    with open(path, "rb") as f:
        head = f.read(24)
    if len(head) < 24 or not head.startswith(PNG_SIGNATURE) or head[12:16] != b"IHDR":
        raise ImageError("is not a PNG image")
    width, height = struct.unpack(">II", head[16:24])
    if not width or not height:
        raise ImageError("is a PNG image of no pixels")
    return width, height


def png_size(path: Path) -> tuple[int, int]:
    """(width, height) from the PNG header, cached by file identity (a replaced file is read again)."""
    st = os.stat(path)
    return _png_size(str(path), st.st_mtime_ns, st.st_size)


def check_profile_image(name: str, path: Path) -> None:
    """Raise ImageError unless ``path`` is a PNG within the profile pixel limit."""
    try:
        width, height = png_size(path)
    except ImageError as exc:
        raise ImageError(f"profile {name!r} {exc}") from None
    except OSError:
        raise ImageError(f"profile {name!r} cannot be read") from None
    limit = profile_pixel_limit()
    if width * height > limit:
        raise ImageError(f"profile {name!r} is {width} x {height} px: at most {limit} pixels "
                         "(max_profile_pixels)")
