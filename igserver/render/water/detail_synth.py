"""One detail map's levels for a frame (detail.py ``detail_map_levels``), with everything that depends on
the tile's lattice (m, n, A k) and the resolution alone computed once per lattice, and per frame only
what depends on the waves' phases φ.

A level of S texels a side is the inverse DFT of ½ G (g_x + i g_y) e^{±iψ} at the bins ±(m, n) mod S,
ψ = φ + π (m + n) / S (the phase at the level's texel centres), G the wave's gain there (every level
of the band-limited chain, level 0 included: detail_mips.py ``_gain``; the box chain's level 0: 1).
Each coefficient is c_± e^{±iφ}, with c_± = ½ G (g_x + i g_y) e^{±iπ (m + n) / S} fixed: a frame's
spectra of all levels are the fixed c_± times the frame's phasors, summed per bin (the box chain's
level 0 may fold a wave past its Nyquist onto another's bin). The spectrum's rows holding no bin are
zero: the inverse DFT's pass along m skips them. The
variance a level's gains removed, Σ (1 − G_i G_j) g_i g_j w_ij (detail_mips.py), is nonzero only
for the pairs of waves on the same or opposite lattice points, w = ½ cos(φ_i ∓ φ_j): fixed weights
(1 − G_i G_j) g_i g_j per pair and level times the pairs' cosines.

The same values as detail_mips.py ``band_limited_levels`` (its tests' reference), within float32's
rounding (the sums run in another order, the inverse DFTs in complex64).
"""

from __future__ import annotations

import functools
import math
import threading

import numpy as np

from .detail_mips import _gain


class TilePairs:
    """A tile's slope amplitude vectors g_i and its pairs of waves on the same or opposite lattice
    points (the only ones whose product averages to nonzero over the tile: ``detail_means``)."""

    def __init__(self, lattice: np.ndarray):
        mn = lattice[:, 0:2]
        self.mn = mn
        self.g = lattice[:, 2:3] * mn / np.linalg.norm(mn, axis=1, keepdims=True)
        # Each wave with itself: w_ii = ½ whatever the phase; the other pairs' w follow the phases.
        self.square = self.g * self.g
        self.fixed = 0.5 * np.sum(self.square, axis=0)  # Σ ½ g_i² (sx², sy²)
        i, j, self.sign = _pairs(mn)
        self.i, self.j = i, j
        self.gg = np.stack([self.g[i, 0] * self.g[j, 0], self.g[i, 1] * self.g[j, 1]])

    def weights(self, phase: np.ndarray) -> np.ndarray:
        """Per pair of two waves (``i``, ``j``), w_ij = the tile average of cos θ_i cos θ_j."""
        return 0.5 * np.cos(phase[self.i] + self.sign * phase[self.j])

    def mean_square(self, phase: np.ndarray) -> np.ndarray:
        """The tile averages of (sx², sy²)."""
        return self.fixed + np.sum(self.gg * self.weights(phase), axis=1) if len(self.i) else self.fixed.copy()


def _pairs(mn: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The ordered pairs (i, j), i ≠ j, of waves on the same lattice point (sign −1: w follows φ_i − φ_j)
    or on opposite ones (+1: φ_i + φ_j; the origin is its own opposite), sorted by i then j: found
    through a table of the points (a filled tile's ~1,100 waves: comparing every two took 0.1 s)."""
    points = list(map(tuple, mn.tolist()))
    at: dict[tuple[float, float], list[int]] = {}
    for index, point in enumerate(points):
        at.setdefault(point, []).append(index)
    pairs = {(i, j): -1.0 for i, point in enumerate(points) for j in at[point] if j != i}
    pairs.update({(i, j): 1.0 for i, (m, n) in enumerate(points) for j in at.get((-m, -n), ()) if j != i})
    if not pairs:
        return np.zeros(0, int), np.zeros(0, int), np.zeros(0)
    i, j, sign = zip(*((i, j, sign) for (i, j), sign in sorted(pairs.items())))
    return np.array(i), np.array(j), np.array(sign)


@functools.lru_cache(maxsize=8)
def tile_pairs(lattice: bytes) -> TilePairs:
    """``TilePairs`` of the lattice (m, n, A k) rows given as float64 bytes (the key: its whole input)."""
    return TilePairs(np.frombuffer(lattice).reshape(-1, 3))


def lattice_key(waves: np.ndarray) -> bytes:
    """The time-independent columns (m, n, A k) of a tile's waves, as the caches' key."""
    return np.ascontiguousarray(waves[:, 0:3], dtype=np.float64).tobytes()


class DetailSynth:
    """The fixed part of one map's levels (module docstring) at ``resolution`` texels a side: level 0
    only (``band_limited`` False: the box chain is made from it) or the band-limited chain."""

    def __init__(self, lattice: np.ndarray, resolution: int, band_limited: bool):
        self.pairs = pairs = tile_pairs(lattice_key(lattice))
        count = len(lattice)
        mn = lattice[:, 0:2]
        m, n = mn[:, 0].astype(int), mn[:, 1].astype(int)
        half = 0.5 * (pairs.g[:, 0] + 1j * pairs.g[:, 1])
        sizes = [resolution >> level for level in range(int(math.log2(resolution)) + 1 if band_limited else 1)]
        # Level 0 band-limited too (a wave past half its Nyquist would fold onto a longer one, and a
        # tile filled up to 38.5 cycles holds many at 64² and below); the box chain's level 0 keeps all.
        gains = [_gain(mn, size) for size in sizes] if band_limited else [np.ones(count)]
        # Levels carrying a wave (a spectrum): level 0 and the band-limited ones until none fits.
        self.spectral = [s for s, gain in zip(sizes, gains) if s == resolution or np.any(gain > 0.0)]
        self.sizes = sizes
        # Each spectral level's bins as (row, m) in a block of the rows that hold a bin (the rest of
        # the spectrum is zero: its rows' inverse DFTs along m are zero, so only these are done).
        self.rows, bins, columns, values, start = [], [], [], [], 0
        for size, gain in zip(self.spectral, gains):
            keep = np.nonzero(gain > 0.0)[0]  # |m|, |n| < size / 2: no two kept bins fold together
            shift = math.pi * (m[keep] + n[keep]) / size
            row = np.concatenate([n[keep] % size, -n[keep] % size])
            rows, row = np.unique(row, return_inverse=True)
            self.rows.append((rows, start))
            bins.append(start + row * size + np.concatenate([m[keep] % size, -m[keep] % size]))
            columns += [keep, keep + count]
            values += [half[keep] * gain[keep] * np.exp(1j * shift), half[keep] * gain[keep] * np.exp(-1j * shift)]
            start += len(rows) * size
        self.total = start
        # Per coefficient: its bin (an index of the distinct bins ``bins``), its phasor's column in
        # (e^{iφ}, e^{−iφ}) and c_±; summed per bin in this order by bincount (no BLAS call: its threads
        # would wait for cores that llvmpipe's rasterizer holds) where two share a bin, else each put
        # in its bin (a filled tile: every point once).
        self.entry_bins = np.concatenate(bins)
        self.bins, self.slot = np.unique(self.entry_bins, return_inverse=True)
        self.shared_bins = len(self.bins) < len(self.entry_bins)
        self.columns, self.values = np.concatenate(columns), np.concatenate(values)
        self.flat = np.zeros(self.total, np.complex64)  # the levels' row blocks: zero but on the bins
        # Per level, the variance its gains removed (sx², sy²): each wave's own ½ (1 − G²) g² (fixed),
        # and per pair of two waves (1 − G_i G_j) g_i g_j w_ij (levels × 2 rows, times w each frame).
        self.removed_fixed = 0.5 * np.array([(1.0 - gain * gain) @ pairs.square for gain in gains]).T
        lost = np.array([1.0 - gain[pairs.i] * gain[pairs.j] for gain in gains]).reshape(len(gains), len(pairs.i))
        self.removed = np.concatenate([lost * pairs.gg[0], lost * pairs.gg[1]])

    def levels(self, phase: np.ndarray, out: list[np.ndarray] | None = None) -> list[np.ndarray]:
        """The levels for the waves' phases ``phase``: (S, S, 4) float32 (sx, sy, sx², sy²) each, S =
        resolution, /2, .. (band-limited) or level 0 alone; written into ``out`` (arrays of those
        shapes, e.g. the last frame's: no fresh pages to fault in) when given."""
        if out is None:
            out = [np.empty((size, size, 4), np.float32) for size in self.sizes]
        rotor = np.exp(1j * phase)
        terms = self.values * np.concatenate([rotor, rotor.conj()])[self.columns]
        removed = self.removed_fixed  # (sx², sy²) per level
        if len(self.pairs.i):
            removed = removed + np.sum(self.removed * self.pairs.weights(phase), axis=1).reshape(2, -1)
        with _LOCK:
            flat = self.flat
            if self.shared_bins:
                flat.real[self.bins] = np.bincount(self.slot, terms.real, len(self.bins))
                flat.imag[self.bins] = np.bincount(self.slot, terms.imag, len(self.bins))
            else:
                flat[self.entry_bins] = terms
            for level, (size, texels) in enumerate(zip(self.sizes, out)):
                extra = removed[:, level]
                if level >= len(self.spectral):  # no wave fits: zero slope, the tile's slope variance
                    texels[...] = (0.0, 0.0, *extra)
                    continue
                # Σ X e^{+2πi (m i + n j) / S} (no 1/S² factor): ifft2's two passes, along m only on the
                # rows holding a bin (the others' are zero), then along n
                rows, start = self.rows[level]
                along_m, s, square = _grid(size, rows)
                block = flat[start:start + len(rows) * size].reshape(-1, size)
                along_m[rows] = np.fft.ifft(block, axis=1, norm="forward")
                np.fft.ifft(along_m, axis=0, norm="forward", out=s)
                texels[..., 0], texels[..., 1] = s.real, s.imag
                for channel, part, add in ((2, s.real, extra[0]), (3, s.imag, extra[1])):
                    np.add(np.multiply(part, part, out=square), add, out=texels[..., channel])
        return out


# Work arrays shared by every DetailSynth (one set per level size; the lock: one user at a time).
# The inverse DFTs run in complex64 (numpy's pocketfft keeps the precision: 3.5x faster than complex128
# at 128²): their rounding, a few 1e-7 of the map's largest slope, is that of the float32 texels.
_LOCK = threading.Lock()
_WORK: dict = {}


def _grid(size: int, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A level's (along m: zero but on ``rows``, which the caller fills; the field; a float64 square)."""
    held = _WORK.get(size)
    if held is None:
        held = _WORK[size] = (np.zeros((size, size), np.complex64), np.empty((size, size), np.complex64),
                              np.empty((size, size), np.float32), [np.arange(0)])
    along_m, s, square, last = held
    along_m[last[0]] = 0.0
    last[0] = rows
    return along_m, s, square


@functools.lru_cache(maxsize=8)
def detail_synth(lattice: bytes, resolution: int, band_limited: bool) -> DetailSynth:
    """The ``DetailSynth`` of the lattice (m, n, A k) rows given as float64 bytes (``lattice_key``), the
    resolution and the chain's kind: the key is the whole input, so a changed sea or knob builds anew."""
    return DetailSynth(np.frombuffer(lattice).reshape(-1, 3), resolution, band_limited)
