"""2D profiles (a vertical slice through the effect's axis, revolved about it; docs/design.md#fire-and-smoke).

A profile is float32 (V, U, 4): row j is the height v = (j + 0.5) / V in [0,1] of the container,
column i the distance from the axis u = (i + 0.5) / U in [0,1] of the container's radius.
Channels: rgb = colour (fire: linear emitted colour, max ~1, scaled by the effect's luminance;
smoke: albedo), a = density (relative extinction, 0..1).

Fire colour follows temperature: blackbody chromaticity from Planck's law integrated against the
CIE 1931 observer (planck.py; ~1500 K orange-red, ~2000 K yellow-orange), with brightness compressed to Tn^1.5 (a real 1000 K edge is ~1e-3 of a 1500 K core; the display
could not show both, a trainee expects to see the red tips).
"""

from __future__ import annotations

import os
from functools import lru_cache

import numpy as np

from ...effect_kinds import EFFECT_KINDS
from ...photometry import LUMA
from .planck import blackbody_chromaticity

PROFILE_U = 64
PROFILE_V = 128
MAX_PROFILE_PIXELS = 4096 * 4096  # a profile is resampled to PROFILE_V x PROFILE_U: more is only memory
SMOKE_ALBEDO = 0.55  # light grey smoke
PLUME_VIRTUAL_ORIGIN = 0.43  # container heights below the base: a plume 0.3 of its top's width there


def blackbody_rgb(kelvin) -> np.ndarray:
    """Linear RGB chromaticity (max channel 1) of a blackbody at ``kelvin`` (array or scalar)."""
    return blackbody_chromaticity(kelvin)


def _smoothstep(e0, e1, x):
    t = np.clip((x - e0) / (e1 - e0), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def _grid() -> tuple[np.ndarray, np.ndarray]:
    u = (np.arange(PROFILE_U) + 0.5) / PROFILE_U
    v = (np.arange(PROFILE_V) + 0.5) / PROFILE_V
    return np.meshgrid(u, v)  # (V, U)


def fire_profile() -> np.ndarray:
    u, v = _grid()
    # Envelope: flared at the pool, narrowing to the tip; density soft inside the envelope.
    r = 0.95 * (1.0 - v) ** 0.6 * (1.0 + 0.05 * np.exp(-v / 0.05))
    r = np.clip(r, 1e-3, 0.98)
    density = _smoothstep(r, 0.7 * r, u) * _smoothstep(1.0, 0.55, v)
    # Temperature: nearly flat across the flame (the soot glows right out to the flame sheet),
    # falling at the envelope and upward to the tips.
    tn = np.clip((1.0 - (u / r) ** 4) * (1.0 - 0.6 * v), 0.0, 1.0)
    colour = blackbody_rgb(1000.0 + 520.0 * tn) * (0.04 + tn**1.5)[..., None]
    return np.dstack([colour, density]).astype(np.float32)


def gas_burner_profile() -> np.ndarray:
    u, v = _grid()
    r = np.clip(0.9 * (1.0 - v) ** 0.45, 1e-3, 0.98)
    outer = _smoothstep(r, 0.6 * r, u) * _smoothstep(1.0, 0.85, v)
    # Premixed inner cone: blue (CH*, C2* emission), a thin sheet, nearly transparent.
    cone_r = np.clip(0.55 * (1.0 - v / 0.4), 0.0, None)
    cone = _smoothstep(0.12, 0.0, np.abs(u - cone_r)) * (v < 0.4)
    blue = np.array([0.25, 0.45, 1.0])
    tip = blackbody_rgb(1400.0) * 0.35
    colour = cone[..., None] * blue * 0.9 + (outer * (1.0 - cone))[..., None] * tip * _smoothstep(0.2, 0.6, v)[..., None]
    density = 0.25 * outer + 0.35 * cone
    return np.dstack([colour, density]).astype(np.float32)


def smoke_profile(albedo: float = SMOKE_ALBEDO) -> np.ndarray:
    u, v = _grid()
    # A buoyant plume (Morton, Taylor & Turner 1956) entrains air at its edge and widens linearly
    # from a virtual origin below its base: r = a (v + v0), here 0.3 of the container's radius at
    # the base and 1 at the top. Its smoke, mixed into ever more air, thins as c ~ (v + v0)^(-5/3),
    # so the optical depth across it falls only as (v + v0)^(-2/3): the plume stays visible to the
    # container's top, where it fades out over the last fifth. Its edge is turbulent but sharp (half
    # density at 0.8 r): a fire's plume opens at 7.4 deg (effects.py PLUME_SPREAD).
    v0 = PLUME_VIRTUAL_ORIGIN
    r = (v + v0) / (1.0 + v0)
    density = (_smoothstep(r, 0.6 * r, u) * (v0 / (v + v0)) ** (5.0 / 3.0) * _smoothstep(0.0, 0.08, v)
               * _smoothstep(1.0, 0.8, v))
    colour = np.full(u.shape + (3,), albedo)
    return np.dstack([colour, density]).astype(np.float32)


PROCEDURAL = {"fire": fire_profile, "gas_burner": gas_burner_profile, "smoke": smoke_profile}  # EffectKind.profile


def procedural(kind: str) -> np.ndarray:
    """The procedural profile of effect kind ``kind``."""
    return PROCEDURAL[EFFECT_KINDS[kind].profile]()


def _srgb_to_linear(c: np.ndarray) -> np.ndarray:
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


@lru_cache(maxsize=32)
def _image_profile(path: str, mtime: float) -> np.ndarray:
    from PIL import Image

    with Image.open(path) as img:
        if img.width * img.height > MAX_PROFILE_PIXELS:  # read from the header: refused before decoding
            raise ValueError(f"profile image over {MAX_PROFILE_PIXELS} pixels")
        has_alpha = "A" in img.getbands()
        rgba = np.asarray(img.convert("RGBA"), dtype=np.float64) / 255.0
    rgb = _srgb_to_linear(rgba[..., :3])
    alpha = rgba[..., 3] if has_alpha else rgb @ LUMA
    data = np.dstack([rgb, alpha])[::-1]  # image top row = top of the container (v = 1)
    # The slice has the axis at its horizontal centre: average the two half-slices outward.
    w = data.shape[1]
    right = data[:, w // 2:]
    left = data[:, : w - w // 2][:, ::-1]
    half = 0.5 * (right + left[:, : right.shape[1]])
    # Resample to the profile grid (bilinear via separable interpolation).
    src_v = (np.arange(half.shape[0]) + 0.5) / half.shape[0]
    src_u = (np.arange(half.shape[1]) + 0.5) / half.shape[1]
    u, v = _grid()
    out = np.empty((PROFILE_V, PROFILE_U, 4))
    for c in range(4):
        rows = np.stack([np.interp(u[0], src_u, half[j, :, c]) for j in range(half.shape[0])])
        out[..., c] = np.stack([np.interp(v[:, 0], src_v, rows[:, i]) for i in range(PROFILE_U)], axis=1)
    return out.astype(np.float32)


def load_profile(kind: str, path: str | None) -> np.ndarray:
    """The profile of effect kind ``kind``; an image file when ``path`` names a readable one (else procedural).

    Image: a vertical slice through the axis, axis at the horizontal centre, top row = top of the
    container; sRGB colour, alpha = density (luminance when there is no alpha). For a scattering
    kind (smoke) the colour's luminance is the albedo.
    """
    if path:
        try:
            profile = _image_profile(path, os.path.getmtime(path)).copy()
        except Exception:  # changed on disk since it was validated (a bomb, a broken file): never fail a frame
            profile = procedural(kind)
        if EFFECT_KINDS[kind].shading == "scattering":
            lum = profile[..., :3] @ LUMA.astype(np.float32)
            profile[..., :3] = lum[..., None]
        return profile
    return procedural(kind)
