"""Band-limited mip levels of a detail map (detail.py ``detail_synth_tables``): each level the tile's waves
that level can carry, the others' slope variance moved into its second moments (the roughness).

Why: the 2×2 box average of the level above passes a wave near a level's Nyquist frequency at up to
2/π of its amplitude and folds it onto a longer one, and the sampler's bilinear filter then draws
the coarse level's texel grid: a tile of a dozen waves seen level from 2 m showed a diamond lattice
on the near water, its cells the coarse levels' texels, crawling as the camera moved. Here a level of
N_L texels a side is the inverse DFT of the waves (m, n) with gain G = 1 − smoothstep(½, 1,
max(|m|, |n|) / (N_L / 2)) (the whole wave up to half its Nyquist, none at it: nothing aliases),
sampled at its own texel centres, and its (sx², sy²) channels hold sx² + the variance the gains
removed, Σ (1 − G_i G_j) g_i g_j w_ij (the same lattice-point pairing as ``detail_means``): the
footprint's mean square slope, so the roughness (LEAN mapping) is as before and the 1×1 level is the
tile average ``detail_means`` computes. The sampler reads the nearest level, bilinear (water.py).

``band_limited_levels`` builds each level directly from the waves, as stated here: the tests' reference
for detail_synth.py, whose compute passes make the same levels each frame from what it keeps per tile
lattice.
"""

from __future__ import annotations

import math

import numpy as np


def _gain(mn: np.ndarray, n_level: int) -> np.ndarray:
    """Per wave, its gain on a level of ``n_level`` texels a side (1 up to half its Nyquist, 0 at it)."""
    f = np.max(np.abs(mn), axis=1) / (0.5 * n_level)
    x = np.clip((f - 0.5) / 0.5, 0.0, 1.0)
    return 1.0 - x * x * (3.0 - 2.0 * x)


def _pairing(mn: np.ndarray, phase: np.ndarray) -> np.ndarray:
    """w_ij: the tile average of cos θ_i cos θ_j — ½ cos(φ_i − φ_j) for waves on the same lattice point,
    ½ cos(φ_i + φ_j) on opposite ones, 0 otherwise (``detail_means``)."""
    same = np.all(mn[:, None] == mn[None], axis=2)
    opposite = np.all(mn[:, None] == -mn[None], axis=2)
    return 0.5 * (same * np.cos(phase[:, None] - phase[None]) + opposite * np.cos(phase[:, None] + phase[None]))


def band_limited_levels(waves: np.ndarray, n_side: int) -> list[np.ndarray]:
    """The levels (N, N/2, .. 1 texels a side) of the map of ``waves`` (m, n, A k, phase), each
    (N_L, N_L, 4) float32 (sx, sy, sx², sy²), rows along the tile's y (as the maps' textures):
    the direct construction (tests' reference; the pass uses detail_synth.py). Level 0 is band-limited
    as the others: a tile filled up to 38.5 cycles (detail.py) holds waves past its Nyquist at 64²."""
    mn = waves[:, 0:2]
    g = waves[:, 2:3] * mn / np.linalg.norm(mn, axis=1, keepdims=True)
    m, n = mn[:, 0].astype(int), mn[:, 1].astype(int)
    w = _pairing(mn, waves[:, 3])
    levels = []
    size = n_side
    while size >= 1:
        gain = _gain(mn, size)
        if not np.any(gain > 0.0):  # no wave fits (the coarse levels: every wave spans >= 5 cycles a tile)
            levels.extend(_flat_levels(g, w, size))
            break
        half = 0.5 * gain * (g[:, 0] + 1j * g[:, 1])
        psi = waves[:, 3] + math.pi * (m + n) / size  # the phase at this level's texel centres
        spectrum = np.zeros((size, size), dtype=complex)
        keep = gain > 0.0  # |m|, |n| < size / 2: no two kept bins fold together
        np.add.at(spectrum, (n[keep] % size, m[keep] % size), half[keep] * np.exp(1j * psi[keep]))
        np.add.at(spectrum, (-n[keep] % size, -m[keep] % size), half[keep] * np.exp(-1j * psi[keep]))
        s = np.fft.ifft2(spectrum, norm="forward")
        removed = w * (1.0 - gain[:, None] * gain[None])
        level = np.empty((size, size, 4), np.float32)
        level[..., 0], level[..., 1] = s.real, s.imag
        level[..., 2] = s.real * s.real + g[:, 0] @ removed @ g[:, 0]
        level[..., 3] = s.imag * s.imag + g[:, 1] @ removed @ g[:, 1]
        levels.append(level)
        size //= 2
    return levels


def _flat_levels(g: np.ndarray, w: np.ndarray, size: int) -> list[np.ndarray]:
    """Levels ``size``, size / 2, .. 1 when none carries a wave: zero slope, and all of the tile's slope
    variance in the second moments (what the inverse DFT of an empty spectrum gives, without it)."""
    moments = np.array([0.0, 0.0, g[:, 0] @ w @ g[:, 0], g[:, 1] @ w @ g[:, 1]], dtype=np.float32)
    levels = []
    while size >= 1:
        levels.append(np.broadcast_to(moments, (size, size, 4)).copy())
        size //= 2
    return levels
