"""The per-wave field over a bathymetry, sampled at points the way the shader samples it.

The field's values at its nodes (residual phase, amplitude factor, wave vector per wave; the
steepness and the depth) are laid out node-major once per field, then interpolated bilinearly at the
points' fractional node coordinates, clamped at the grid's edges like gerstner.glsl's texture fetch.
"""

from __future__ import annotations

import numpy as np

from .bathymetry import WaveField
from .workspace import _Work


_NODES: dict[int, tuple[WaveField, tuple[np.ndarray, np.ndarray]]] = {}


def _field_nodes(f: WaveField) -> tuple[np.ndarray, np.ndarray]:
    """The field's per-wave node values node-major, (nu·nv, 4n + 2): R, F, Kx, Ky of every wave (n
    each), then Q and the depth — one gather of rows fetches all of the points' parameters; and their differences
    to the next node along u (the lerp's slope, the same float64 value it would compute)."""
    cached = _NODES.get(id(f))
    if cached is None or cached[0] is not f:
        n, nu, nv = f.residual.shape
        stacked = np.concatenate([f.residual, f.factor, f.kvec[..., 0], f.kvec[..., 1], f.steepness[None],
                                  f.depth[None]])
        nodes = np.ascontiguousarray(stacked.transpose(1, 2, 0))  # (nu, nv, 4n + 1)
        slope = np.zeros_like(nodes)
        slope[:-1] = nodes[1:] - nodes[:-1]  # the last node: clamped, i1 = i0 (never used with tu > 0)
        cols = nodes.shape[-1]
        if len(_NODES) > 8:
            _NODES.clear()
        _NODES[id(f)] = cached = (f, (nodes.reshape(nu * nv, cols), slope.reshape(nu * nv, cols)))
    return cached[1]


def _interpolate(table: tuple[np.ndarray, np.ndarray], grid: tuple[int, int], gu: np.ndarray, gv: np.ndarray,
                 w: "_Work") -> np.ndarray:
    """Bilinear interpolation of node values (nu·nv, m) at fractional node coordinates (N,) → (m, N),
    wave-major — the grid clamped at its edges, as the shader's clamp-to-edge texel-centre fetch
    (gerstner.glsl); linear along u alone on a one-row grid (the plane beach). Gathered point-major
    (contiguous node rows; mode "clip": the indices are in range, and numpy buffers ``out`` under the
    default "raise" — 3x slower), transposed once."""
    values, slope = table
    nu, nv = grid
    npts, cols = len(gu), values.shape[1]
    i0 = np.minimum(np.floor(gu).astype(np.intp), max(nu - 2, 0))
    tu = (gu - i0)[:, None]
    lo, hi = w.get("lerp_lo", (npts, cols)), w.get("lerp_hi", (npts, cols))
    j0 = np.minimum(np.floor(gv).astype(np.intp), max(nv - 2, 0)) if nv > 1 else np.zeros(npts, np.intp)
    np.take(values, i0 * nv + j0, axis=0, out=lo, mode="clip")
    np.take(slope, i0 * nv + j0, axis=0, out=hi, mode="clip")
    hi *= tu
    lo += hi  # along u at j0
    if nv > 1:
        j1 = np.minimum(j0 + 1, nv - 1)
        tv = (gv - j0)[:, None]
        top = w.get("lerp_top", (npts, cols))
        np.take(values, i0 * nv + j1, axis=0, out=top, mode="clip")
        np.take(slope, i0 * nv + j1, axis=0, out=hi, mode="clip")
        hi *= tu
        top += hi  # along u at j1
        top -= lo
        top *= tv
        lo += top
    out = w.get("lerp", (cols, npts))
    np.copyto(out, lo.T)
    return out
