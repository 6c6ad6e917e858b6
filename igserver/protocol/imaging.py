"""Frame encoders: JPEG (simplejpeg, chosen by measurement), PNG (Pillow), raw RGBA.

``compare_jpeg_encoders`` is the measurement: at 640x360 simplejpeg (libjpeg-turbo, encodes RGBA
directly, releases the GIL) beats Pillow, which must first copy RGBA into an RGB image. Run
``python -m igserver.protocol.imaging`` to repeat it.
"""

from __future__ import annotations

import io
import time
from typing import Callable

import numpy as np
import simplejpeg
from PIL import Image

FORMATS = ("jpeg", "png", "raw")
MEDIA_TYPES = {"jpeg": "image/jpeg", "png": "image/png", "raw": "application/octet-stream"}


def jpeg_simplejpeg(rgba: np.ndarray, quality: int) -> bytes:
    return simplejpeg.encode_jpeg(rgba, quality=quality, colorspace="RGBA", colorsubsampling="420", fastdct=True)


def jpeg_pillow(rgba: np.ndarray, quality: int) -> bytes:
    out = io.BytesIO()
    Image.fromarray(rgba[:, :, :3]).save(out, format="JPEG", quality=quality, subsampling=2)
    return out.getvalue()


JPEG_ENCODERS: dict[str, Callable[[np.ndarray, int], bytes]] = {
    "simplejpeg": jpeg_simplejpeg,
    "pillow": jpeg_pillow,
}
JPEG_ENCODER = "simplejpeg"  # by measurement, see compare_jpeg_encoders


def encode_frame(rgba: np.ndarray, fmt: str, quality: int = 85) -> bytes:
    if fmt == "jpeg":
        return JPEG_ENCODERS[JPEG_ENCODER](rgba, quality)
    if fmt == "png":
        out = io.BytesIO()
        # level 1: a PNG is asked for to be lossless, not small; level 6 costs ~5x the time
        Image.fromarray(rgba, mode="RGBA").save(out, format="PNG", compress_level=1)
        return out.getvalue()
    if fmt == "raw":
        return rgba.tobytes()
    raise ValueError(f"unknown frame format {fmt!r}")


def compare_jpeg_encoders(rgba: np.ndarray, quality: int = 85, repeats: int = 50) -> dict[str, dict[str, float]]:
    """Median and p99 encode time (ms) and size (bytes) of each JPEG encoder on one frame."""
    results = {}
    for name, encoder in JPEG_ENCODERS.items():
        encoder(rgba, quality)  # warm-up
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            data = encoder(rgba, quality)
            times.append((time.perf_counter() - t0) * 1e3)
        times.sort()
        results[name] = {
            "median_ms": times[len(times) // 2],
            "p99_ms": times[min(len(times) - 1, int(len(times) * 0.99))],
            "bytes": len(data),
        }
    return results


def _test_image(width: int = 640, height: int = 360) -> np.ndarray:
    # smooth gradients plus noise: closer to a rendered sky/sea than a flat colour
    y, x = np.mgrid[0:height, 0:width]
    rng = np.random.default_rng(1)
    img = np.stack([x * 255 // width, y * 255 // height, (x + y) * 255 // (width + height), np.full_like(x, 255)], -1)
    img = img + rng.integers(0, 12, img.shape)
    return np.clip(img, 0, 255).astype(np.uint8)


if __name__ == "__main__":
    for name, r in compare_jpeg_encoders(_test_image()).items():
        print(f"{name:10s} median {r['median_ms']:.2f} ms  p99 {r['p99_ms']:.2f} ms  {r['bytes']} bytes")
