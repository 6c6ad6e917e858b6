"""The detail maps' levels for a frame (detail.py ``detail_synth_tables`` states them), made on the GL by
four compute passes from tables uploaded once per tile lattice and resolution; per frame only the time.

A level of S texels a side is the inverse DFT of ½ G (g_x + i g_y) e^{±iψ} at the bins ±(m, n) mod S,
ψ = φ + π (m + n) / S (the phase at the level's texel centres), G the wave's gain there (every level
of the band-limited chain, level 0 included: detail_mips.py ``_gain``). Each coefficient is c_± e^{±iφ},
c_± = ½ G (g_x + i g_y) e^{±iπ (m + n) / S} fixed. The tables hold per wave ω, φ0 (φ = φ0 − ω t) and
m + n; per bin its coefficients c_± and their waves; per level of each map the rows of its spectrum
that hold a bin (the others are zero, and so are their inverse DFTs along m, which are skipped).
The passes, each reading what the one before wrote (a memory barrier between):

1. detail_waves.comp.glsl: each wave's phasor e^{iφ}, φ reduced in double precision (t reaches 1e9 s).
2. detail_bins.comp.glsl: each bin's Σ c_± e^{±iφ}, gathered from its coefficients (no atomics; a
   filled tile has one a bin, the snapped waves may share one).
3. detail_rows.comp.glsl: the inverse DFT along m of each row that holds a bin, two a task (their
   spectra interleaved: a point of both is one load; an odd row's partner a spare row).
4. detail_columns.comp.glsl: the inverse DFT along n of each column, four a task (x .. x + 3), written
   as (sx, sy, sx² + r_x, sy² + r_y) into the level's texels, each level then copied into its mip
   level of the map.

The variance r that a level's gains removed, Σ (1 − G_i G_j) g_i g_j w_ij (detail_mips.py), is a
fixed Σ ½ (1 − G_i²) g_i² per wave and, for the pairs of waves on the same or opposite lattice
points (w = ½ cos(φ_i ∓ φ_j)), a fixed weight (1 − G_i G_j) g_i g_j per pair and level times the
frame's cosine, summed by the last pass (a filled tile has no such pair: none is summed, and its
levels' r is a constant of the table).

The same values as detail_mips.py ``band_limited_levels`` (the tests' reference) within float32's
rounding, 3e-7 of the map's largest slope: the phases are reduced in double precision, their sines
and the DFTs run in float. On llvmpipe a storage access costs a loop over the lanes whatever its
width: the rows' pass reads pairs (vec4), the columns' pass quads and pairs of texels (8 floats, a
dvec4 of their bits).
"""

from __future__ import annotations

import functools
import math

import moderngl
import numpy as np

from ..bindings import STORAGE
from ..shaders import GENERATED, set_uniforms
from .detail_fft import RADIX, fft_glsl
from .detail_mips import _gain

# The passes' DFTs, included like a package file (shaders.py read_glsl: the text made once a process).
GENERATED.setdefault("generated/detail_fft.glsl", fft_glsl)


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

    def turning(self, omega: np.ndarray) -> np.ndarray:
        """Per pair, whether its w_ij follows t for the waves' ω (rad/s): a pair on opposite points
        (φ_i + φ_j = φ0_i + φ0_j − (ω_i + ω_j) t) or of unequal ω. Two waves on one lattice point share
        ω (one k): their φ_i − φ_j, and so w_ij, is the same at every t."""
        return (self.sign > 0.0) | (omega[self.i] != omega[self.j])

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


# The passes' work-group sizes (local_size_x): an invocation per wave or bin, 128 a group (llvmpipe's
# cost per group: 25 % of the bins' pass at 8, 10 % at 32, none measured past 128); an invocation per
# two rows or four columns, 8 a group (a vector on llvmpipe), each level's rows and columns starting on a
# group of their own (padded).
GROUP = 8
WIDE_GROUP = 128
_ENTRY = np.dtype([("value", "<f4", 2), ("wave", "<i4"), ("unused", "<i4")])  # one vec4 (bins' pass)
_LEVEL = np.dtype([("size", "<i4"), ("along", "<i4"), ("first", "<i4"), ("spectral", "<i4"),
                   ("removed", "<f4", 2), ("pair_first", "<i4"), ("pair_end", "<i4"), ("texels", "<i4"),
                   ("unused", "<i4", 3)])
_PAIR = np.dtype([("weight", "<f4", 2), ("i", "<i4"), ("j", "<i4")])


def _padded(count: int) -> int:
    return -(-count // GROUP) * GROUP


class SynthTables:
    """What the passes read of the maps' tiles at ``resolution`` texels a side (the module docstring),
    as the bytes of their storage buffers; ``tiles``: per map, (m, n, A k) of its waves, their ω (rad/s)
    and φ0 (rad). Every table runs map by map: ``ends[c]``, the waves, bins, rows, levels and column
    invocations of the first c + 1 maps (a frame writes a prefix of the maps); ``levels[c]``, per level
    of map c, (its first texel in the texel buffer, S)."""

    def __init__(self, tiles, resolution: int):
        self.resolution = resolution
        sizes = [resolution >> level for level in range(int(math.log2(resolution)) + 1)]
        waves, bins, entries, rows, levels, pairs = [], [], [], [], [], []
        self.ends, self.levels, self.varies = [], [], []
        base = texels = columns = 0
        place = sum(len(fixed) for fixed, _, _ in tiles)  # the phasors first in the grid
        count = {"bins": 0, "entries": 0, "rows": 0, "pairs": 0}
        for fixed, omega, phase in tiles:
            fixed = np.asarray(fixed, dtype=np.float64)
            map_levels, map_varies = [], []
            if len(fixed):
                tile = TilePairs(fixed)
                mn = fixed[:, 0:2]
                m, n = mn[:, 0].astype(int), mn[:, 1].astype(int)
                waves.append(np.column_stack([omega, phase, m + n, np.zeros(len(m))]))
            for size in sizes if len(fixed) else []:
                gain = _gain(mn, size)
                keep = np.nonzero(gain > 0.0)[0]  # |m|, |n| < size / 2: no two kept bins fold together
                record = np.zeros((), _LEVEL)
                record["size"], record["first"], record["spectral"] = size, columns, int(len(keep) > 0)
                record["removed"] = 0.5 * ((1.0 - gain * gain) @ tile.square)
                record["texels"] = texels
                map_levels.append((texels, size))
                if len(keep):
                    # The bins +(m, n) and −(m, n) mod S of each kept wave, in the rows that hold one.
                    row = np.concatenate([n[keep] % size, -n[keep] % size])
                    column = np.concatenate([m[keep] % size, -m[keep] % size])
                    held, row = np.unique(row, return_inverse=True)
                    # The held rows in pairs (2p, 2p + 1), their spectra interleaved (a pair's point m
                    # one vec4: one load), an odd last row paired with a spare row that nothing reads;
                    # the grid even (the columns read pairs of points).
                    pairs_held = -(-len(held) // 2)
                    spectrum = place + place % 2
                    spare = spectrum + 2 * pairs_held * size
                    along = -(-(spare + size) // 4) * 4  # a multiple of 4: the columns read quads
                    place = along + size * size
                    # Per distinct bin its coefficients, in wave order (stable sort).
                    key = row * size + column
                    order = np.argsort(key, kind="stable")
                    at, start = np.unique(key[order], return_index=True)
                    half = 0.5 * gain[keep] * (tile.g[keep, 0] + 1j * tile.g[keep, 1])
                    shift = np.exp(1j * math.pi * (m[keep] + n[keep]) / size)
                    value = np.concatenate([half * shift, half * shift.conj()])[order]
                    entry = np.zeros(len(order), _ENTRY)
                    entry["value"] = np.column_stack([value.real, value.imag])
                    entry["wave"] = np.concatenate([base + keep, ~(base + keep)])[order]
                    first = count["entries"] + start
                    slot = spectrum + 2 * ((at // size // 2) * size + at % size) + at // size % 2
                    bins.append(np.column_stack([slot, first, np.append(first[1:], first[0] + len(order)),
                                                 np.zeros(len(at))]))
                    entries.append(entry)
                    # Each pair of held rows a task of the third pass; padded to whole work groups.
                    task = np.zeros((_padded(pairs_held), 4), np.int64)
                    task[:, 0], task[:, 2] = size, -1
                    task[:pairs_held, 1] = spectrum + 2 * np.arange(pairs_held) * size
                    out = np.append(along + held * size, spare)
                    task[:pairs_held, 2], task[:pairs_held, 3] = out[0:2 * pairs_held:2], out[1:2 * pairs_held:2]
                    rows.append(task)
                    record["along"] = along
                    count["bins"] += len(at)
                    count["entries"] += len(entry)
                    count["rows"] += len(task)
                # The pairs whose weight 1 − G_i G_j is not zero on this level.
                lost = 1.0 - gain[tile.i] * gain[tile.j]
                used = np.nonzero(lost != 0.0)[0]
                pair = np.zeros(len(used), _PAIR)
                pair["weight"] = (lost[used] * tile.gg[:, used]).T
                pair["i"] = base + tile.i[used]
                pair["j"] = np.where(tile.sign[used] < 0.0, base + tile.j[used], ~(base + tile.j[used]))
                record["pair_first"], record["pair_end"] = count["pairs"], count["pairs"] + len(pair)
                # A level changes with t when it holds a wave or a pair whose weight turns; one of
                # still pairs only, (0, 0, removed), is the same at every t.
                map_varies.append(bool(len(keep)) or bool(np.any(tile.turning(omega)[used])))
                count["pairs"] += len(pair)
                pairs.append(pair)
                levels.append(record)
                texels += size * size + size * size % 2  # each level's first even (pairs of texels)
                columns += _padded(-(-size // 4))  # an invocation per four columns
            base += len(fixed)
            self.levels.append(map_levels)
            self.varies.append(map_varies)
            self.ends.append({"waves": base, "bins": count["bins"], "rows": count["rows"], "levels": len(levels),
                              "columns": columns})
        self.buffers = {
            "SEA_DETAIL_WAVES": _data(waves, np.float64, (0, 4)),
            "SEA_DETAIL_GRID": bytes(8 * max(place, 1)),  # zero: what no pass writes
            "SEA_DETAIL_BINS": _data(bins, np.int32, (0, 4)),
            "SEA_DETAIL_ENTRIES": _data(entries, _ENTRY, (0,)),
            "SEA_DETAIL_ROWS": _data(rows, np.int32, (0, 4)),
            "SEA_DETAIL_LEVELS": _data([np.array(levels, _LEVEL)] if levels else [], _LEVEL, (0,)),
            "SEA_DETAIL_PAIRS": _data(pairs, _PAIR, (0,)),
            "SEA_DETAIL_TEXELS": bytes(16 * max(texels, 1)),
        }


def _data(parts: list[np.ndarray], dtype, empty_shape) -> bytes:
    """The parts' rows as one buffer's bytes (at least one zero element: GL has no empty buffer)."""
    array = np.concatenate(parts).astype(dtype) if parts else np.zeros(empty_shape, dtype)
    return array.tobytes() or bytes(np.zeros(1, dtype).nbytes * (empty_shape[1] if len(empty_shape) > 1 else 1))


@functools.lru_cache(maxsize=4)
def synth_tables(lattice, resolution: int) -> SynthTables:
    """The ``SynthTables`` of a ``detail.DetailLattice`` (one object per set of detail waves: detail.py
    ``detail_lattice`` caches it by its whole input) at ``resolution``."""
    return SynthTables([(fixed, omega, phase) for _, fixed, omega, phase in lattice.tiles], resolution)


class DetailSynthGL:
    """The synthesis on one GL context: the tables' buffers and a pixel buffer per level (made again
    when the tables change, never per frame) and, per frame, the four passes for the time t and the
    copies of the levels into their textures (a pixel buffer each: moderngl's Texture.write reads a
    buffer from its start). ``maps_written`` counts the maps written (tests: at most once a frame each)."""

    # Per pass: its shader, the uniform that bounds it (the waves, bins or levels of the maps written;
    # the rows pass runs exactly its rows, a whole number of groups), what it runs over, its group size.
    PASSES = (("water/detail_waves.comp.glsl", "u_waves", "waves", WIDE_GROUP),
              ("water/detail_bins.comp.glsl", "u_bins", "bins", WIDE_GROUP),
              ("water/detail_rows.comp.glsl", None, "rows", GROUP),
              ("water/detail_columns.comp.glsl", "u_levels", "columns", GROUP))

    def __init__(self, ctx: moderngl.Context, programs):
        self.ctx, self.programs = ctx, programs
        self._tables: SynthTables | None = None
        self._buffers: dict[str, moderngl.Buffer] = {}
        self._pixels: list[list[moderngl.Buffer]] = []
        self._pending = 0  # maps dispatched and not yet copied into their textures
        # (texture, level) pairs holding a time-independent level of the current tables: not copied again
        self._still: set[tuple[moderngl.Texture, int]] = set()
        self.maps_written = self.levels_copied = 0

    def release(self) -> None:
        for buffer in [*self._buffers.values(), *(b for level in self._pixels for b in level)]:
            buffer.release()
        self._buffers, self._pixels, self._tables = {}, [], None
        self._still = set()

    def write(self, textures, tables: SynthTables, t: float, maps: int) -> None:
        """Write every level of the first ``maps`` maps of ``tables`` into ``textures`` (rgba32f, each
        with its whole mip chain allocated) for the time ``t`` (s): ``dispatch`` then ``copy``."""
        self.dispatch(tables, t, maps)
        self.copy(textures)

    def dispatch(self, tables: SynthTables, t: float, maps: int) -> None:
        """Run the passes for the first ``maps`` maps at the time ``t`` (s); ``copy`` puts their levels
        into the textures. (A GPU runs them while the caller goes on; llvmpipe runs each dispatch to
        its end before returning, on its compute threads.)"""
        if tables is not self._tables:
            self.release()
            self._buffers = {name: self.ctx.buffer(data) for name, data in tables.buffers.items()}
            self._pixels = [[self.ctx.buffer(reserve=16 * size * size) for _, size in levels] for levels in tables.levels]
            self._tables = tables
        ends = tables.ends[maps - 1]
        self._pending = maps if ends["waves"] else 0
        if not self._pending:
            return
        for name, buffer in self._buffers.items():  # other compute passes may bind these points
            buffer.bind_to_storage_buffer(STORAGE[name])
        for path, uniform, end, group in self.PASSES:
            program = self.programs.compute(path, {"DETAIL_N": tables.resolution, "DETAIL_GROUP": group})
            set_uniforms(program, {"u_time": float(t), "u_detail_radix": RADIX,
                                   **({uniform: ends["levels" if end == "columns" else end]} if uniform else {})})
            program.run(-(-ends[end] // group))
            # The next pass reads what this one wrote; after the last, ``copy`` reads it. Every bit, as
            # every compute pass of the frame (tests/test_gl_hazards.py: a GPU may reorder what llvmpipe does not).
            self.ctx.memory_barrier()

    def copy(self, textures) -> None:
        """Copy the levels the last ``dispatch`` made into ``textures`` (its maps', once). A level the
        same at every t (``SynthTables.varies``) is copied once per tables and texture."""
        texels = self._buffers.get("SEA_DETAIL_TEXELS")
        maps = zip(textures[:self._pending], self._tables.levels if texels else [], self._tables.varies, self._pixels)
        for texture, levels, varies, pixels in maps:
            for index, ((first, size), buffer) in enumerate(zip(levels, pixels)):
                if not varies[index]:
                    if (texture, index) in self._still:
                        continue
                    self._still.add((texture, index))
                self.ctx.copy_buffer(buffer, texels, 16 * size * size, read_offset=16 * first)
                texture.write(buffer, level=index)
                self.levels_copied += 1
            self.maps_written += bool(levels)
        self._pending = 0
