"""The sea surface's wave sums and what they give, for the evaluation and the queries of surface.py.

Every sum over the waves at a point is Σ_i cos θ_i · wc_i or Σ_i sin θ_i · ws_i, so each set of them
is one product with a matrix of per-wave weights (``_weights``); from those 13 cosine- and 10 sine-
weighted sums follow the displaced point, the horizontal Jacobian, the height (with the depth limit),
the normal, the velocity, and the Chebyshev update that inverts the horizontal map.
"""

from __future__ import annotations

import numpy as np

from .bathymetry import depth_limit
from .workspace import _Work


def _vertical(cs: np.ndarray, ss: np.ndarray, mu, depth) -> tuple[np.ndarray, ...]:
    """Height, its gradient over the rest point (x, y) and its time derivative from the wave sums:
    z = L(z₁ + z₂) (water/surface.py's docstring), X = Σ s sin θ (ss[6]), Y = Σ s cos θ (cs[9]), ∇X = cs[10:12],
    ∇Y = −ss[7:9], ∂X/∂t = −cs[12], ∂Y/∂t = ss[9]."""
    x, y = ss[6], cs[9]
    z = ss[3] + 0.5 * (x * x + y * y) - mu
    gx = cs[2] + x * cs[10] - y * ss[7]
    gy = cs[3] + x * cs[11] - y * ss[8]
    vz = -cs[4] - x * cs[12] + y * ss[9]
    z, slope = depth_limit(z, depth)
    return z, slope * gx, slope * gy, slope * vz


def _answer(cs: np.ndarray, ss: np.ndarray, out: dict, idx: np.ndarray, mu, depth) -> None:
    """Height, unit normal and velocity from the wave sums, written at ``idx`` of the query's arrays
    (the same formulas as ``_outputs``)."""
    jxx, jxy, jyy = 1.0 - ss[0], -ss[1], 1.0 - ss[2]
    z, gx, gy, vz = _vertical(cs, ss, mu, depth)
    normal = np.empty((len(jxx), 3))
    np.multiply(jxy, gy, out=normal[:, 0])
    normal[:, 0] -= gx * jyy
    np.multiply(gx, jxy, out=normal[:, 1])
    normal[:, 1] -= jxx * gy
    np.multiply(jxx, jyy, out=normal[:, 2])
    normal[:, 2] -= jxy * jxy
    normal /= np.sqrt(np.einsum("ij,ij->i", normal, normal))[:, None]
    out["height"][idx] = z
    out["normal"][idx] = normal
    velocity = out["velocity"]
    velocity[idx, 0], velocity[idx, 1], velocity[idx, 2] = ss[4], ss[5], vz


N_COS, N_SIN = 13, 10  # rows of the cosine- and sine-weighted wave sums


def _weights(a, kx, ky, bk, omega, kmag, alpha: float, w: "_Work | None" = None) -> tuple:
    """Weights of the wave sums, per wave (n,) → (13, n) and (10, n), or per wave and point (n, N) →
    (13, n, N) and (10, n, N); and z₂'s mean ½ Σ s_i² (a number, or (N,)). Cosine-weighted: displacement x, y
    (b K̂ = bk K); ∂z/∂x₀, ∂z/∂y₀ (a K); −∂z/∂t (a ω); the displacement's second derivatives
    −∂²Δ/∂p² = Σ bk K K K cos θ (xxx, xxy, xyy, yyy); Y (s), ∇X (s K), −∂X/∂t (s ω). Sine-weighted:
    M = Σ bk K Kᵀ sin θ (xx, xy, yy), z₁ (a), the horizontal velocity (bk K ω), X (s), −∇Y (s K),
    ∂Y/∂t (s ω). s = a √(α |K|) (water/surface.py's docstring)."""
    shape = np.shape(a)
    wc = np.empty((N_COS, *shape)) if w is None else w.get("wc", (N_COS, *shape))
    ws = np.empty((N_SIN, *shape)) if w is None else w.get("ws", (N_SIN, *shape))
    mul = np.multiply
    mul(bk, kx, out=wc[0])  # bkx
    mul(bk, ky, out=wc[1])  # bky
    mul(a, kx, out=wc[2])
    mul(a, ky, out=wc[3])
    mul(a, omega, out=wc[4])
    mul(wc[0], kx, out=ws[0])  # bkx kx
    mul(wc[0], ky, out=ws[1])  # bkx ky
    mul(wc[1], ky, out=ws[2])  # bky ky
    ws[3] = a
    mul(wc[0], omega, out=ws[4])
    mul(wc[1], omega, out=ws[5])
    mul(ws[0], kx, out=wc[5])  # bkx kx kx
    mul(ws[0], ky, out=wc[6])  # bkx kx ky
    mul(ws[1], ky, out=wc[7])  # bkx ky ky
    mul(ws[2], ky, out=wc[8])  # bky ky ky
    sk = np.sqrt(np.multiply(kmag, alpha, out=ws[6]), out=ws[6])
    mul(sk, a, out=ws[6])  # s
    wc[9] = ws[6]
    mul(ws[6], kx, out=wc[10])
    mul(ws[6], ky, out=wc[11])
    mul(ws[6], omega, out=wc[12])
    ws[7], ws[8], ws[9] = wc[10], wc[11], wc[12]
    mu = 0.5 * np.sum(ws[6] * ws[6], axis=0)  # z₂'s mean
    return wc, ws, mu


def _outputs(p0: np.ndarray, cs: np.ndarray, ss: np.ndarray, full: bool, mu=0.0, depth=np.inf) -> dict:
    """Displaced point, horizontal Jacobian, normal and velocity from the wave sums cs (13, N), ss (10, N)."""
    jxx, jxy, jyy = 1.0 - ss[0], -ss[1], 1.0 - ss[2]
    out = {
        "displaced_xy": p0 + cs[:2].T,
        "horizontal_jacobian": np.stack([np.stack([jxx, jxy], -1), np.stack([jxy, jyy], -1)], -2),
        "jacobian": jxx * jyy - jxy * jxy,
    }
    if not full:
        return out
    # ∂P/∂x0 = (jxx, jxy, gx), ∂P/∂y0 = (jxy, jyy, gy): their cross product, up while J > 0
    z, gx, gy, vz = _vertical(cs, ss, mu, depth)
    normal = np.stack([jxy * gy - gx * jyy, gx * jxy - jxx * gy, out["jacobian"]], axis=1)
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    out["position"] = np.concatenate([out["displaced_xy"], z[:, None]], axis=1)
    out["normal"] = normal
    out["velocity"] = np.stack([ss[4], ss[5], vz], axis=1)
    return out


def _chebyshev_step(err: np.ndarray, cs: np.ndarray, ss: np.ndarray) -> np.ndarray:
    """Chebyshev's update for F(p) = p + Δ(p) − x = err (2, N): s = −J⁻¹F, then s − ½ J⁻¹ F″(s, s),
    with F″ = −Σ bk K K K cos θ (third-order convergence; J symmetric)."""
    jxx, jxy, jyy = 1.0 - ss[0], -ss[1], 1.0 - ss[2]
    det = jxx * jyy - jxy * jxy
    inv = 1.0 / np.where(np.abs(det) > 1e-9, det, 1e-9)
    ex, ey = err
    sx = (jxy * ey - jyy * ex) * inv
    sy = (jxy * ex - jxx * ey) * inv
    sxx, sxy, syy = sx * sx, 2.0 * sx * sy, sy * sy
    # ½ F″(s, s) with F″ = −(cs[5..8]): h = −½ (t0 sx² + 2 t1 sx sy + t2 sy², t1 sx² + 2 t2 sx sy + t3 sy²)
    hx = -0.5 * (cs[5] * sxx + cs[6] * sxy + cs[7] * syy)
    hy = -0.5 * (cs[6] * sxx + cs[7] * sxy + cs[8] * syy)
    step = np.empty_like(err)
    step[0] = sx - (jyy * hx - jxy * hy) * inv
    step[1] = sy - (jxx * hy - jxy * hx) * inv
    return step
