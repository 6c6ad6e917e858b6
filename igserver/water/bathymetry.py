"""Depth under the sea and the per-wave field it imposes (refraction, shoaling, breaking).

Integrated ONCE per (bathymetry, wave set), on a regular grid in a local frame (u, v):

- Phase. Each wave's phase ψ solves the eikonal |∇ψ| = k(h(x)) (ray theory). On a 2D grid (a height
  map) it is the continuous first-arrival (viscosity) solution by fast sweeping (``_eikonal_field``),
  ψ = k_ref·D·x on the inflow edges, dry land an obstacle. On a plane beach (a 1D grid) we march it
  from the up-wave edge along the grid axis (±u) closest to the wave's direction:
  ψ_{j+1} = ψ_j + Δs·√(k² − (∂_c ψ)²), with ∂_c ψ the derivative across the march. For a plane beach
  the grid is one cell wide along the shore and ∂_c ψ = k_ref·D_c is exactly conserved: Snell's law,
  crests turn toward the shore. What the shader stores is the residual R = ψ − k_ref·D·x and the
  local wave vector K = ∇ψ.
- Amplitude. Linear shoaling K_s = √(c_g,ref / c_g(h)) and refraction K_r = √(cos θ_ref / cos θ)
  (θ measured from the march axis: exact for straight parallel contours, the plane beach; an
  approximation over a general height map). Breaking (``surf_cap``): wherever the local linear sea,
  Hs = 4·√(Σ A_i²/2), would exceed SURF_LINEAR_HS·h, all amplitudes are scaled down to it; on dry
  land (h ≤ 0) they are zero. The scale (1 − cap) marks the surf zone. The same cap holds over a
  uniform depth (``reference_waves``): there is no depth without a breaking limit.
- Depth-limited heights. Two published limits, met together:
    * the saturated surf zone (Thornton & Guza 1983, Torrey Pines): Hrms ≈ 0.42·h, i.e. Hs = √2·Hrms
      ≈ 0.59·h (Rayleigh heights: Hm0 = 4σ = √2·Hrms);
    * a single wave breaks beyond H = 0.78·h (McCowan 1894; the solitary wave's limit).
  A linear sum of waves with Hs = 0.59·h has Rayleigh heights up to ~1.9·Hs = 1.1·h and troughs that
  reach the bed. So the elevation itself is bounded (``depth_limit``): z ↦ L(z) is the identity
  for |z| ≤ z₀ and beyond it saturates smoothly toward ±c, c = ½·0.78·h, with
      L(z) = sign z·(z₀ + (c − z₀)·tanh((|z| − z₀)/(c − z₀))),   z₀ = LIMIT_KNEE·c,
  C¹ at z₀ (slope 1) and strictly inside (−c, c): every crest-to-trough height stays below 0.78·h and
  no trough passes −0.39·h. Deep water is untouched (z₀ = 195 m over 1000 m). The bound takes a few
  percent off the variance near the cap, so the linear cap SURF_LINEAR_HS is the Hs whose bounded
  elevation has 4σ = 0.59·h (``_surf_linear_hs``: 0.61·h); below ~0.45·h the bound changes Hs by < 1 %.
- Steepness. Q grows toward the shore with shallowness 1 − tanh(k_p h) (k_p the peak's local
  wavenumber): Q(x) = Q + (Q_SHORE − Q)·(1 − tanh k_p h).

Outside the grid the texture lookups clamp to the border (the beach is invariant along the shore;
around a map the depth is ``bathymetry.depth``, reached through a margin).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..scene.model import Bathymetry
from .dispersion import group_velocity, wavenumber
from .spectrum import WaveSet

BREAKING_RATIO = 0.78  # H / h (McCowan 1894): a single wave breaks beyond it
SURF_HRMS_RATIO = 0.42  # Hrms / h of the saturated surf zone (Thornton & Guza 1983)
SURF_HS_RATIO = math.sqrt(2.0) * SURF_HRMS_RATIO  # Hs / h there: 0.594 (Hm0 = √2·Hrms)
LIMIT_KNEE = 0.5  # z₀ / c: the elevation bound starts at half the largest crest (or trough) ±c = ±0.39 h
Q_SHORE = 0.9  # Gerstner steepness reached in very shallow water
MIN_COS = 0.17  # cos 80°: a ray never turns past 80° from the march axis (caustic guard)
SLOPE_MAX_CELLS = 8192
MAP_MAX_CELLS = 384
DRY_DEPTH = 1e-3  # m: the wavenumber is evaluated at least at this depth (dry cells: amplitude 0)


def depth_limit(z, depth) -> tuple[np.ndarray, np.ndarray]:
    """(L(z), dL/dz): the elevation z (m) bounded inside ±½·BREAKING_RATIO·h over depth h (m; module
    docstring). The identity, bit for bit, wherever |z| ≤ z₀ (all of deep water)."""
    z = np.asarray(z, dtype=np.float64)
    c = 0.5 * BREAKING_RATIO * np.maximum(depth, DRY_DEPTH)
    z0 = LIMIT_KNEE * c
    w = c - z0
    t = np.tanh(np.maximum(np.abs(z) - z0, 0.0) / w)
    return np.sign(z) * (np.minimum(np.abs(z), z0) + w * t), 1.0 - t * t


def _surf_linear_hs() -> float:
    """Hs / h of the linear sea whose bounded elevation L(z) has 4σ = SURF_HS_RATIO·h: σ of L(z) for z
    ~ N(0, s²) by 96-node Gauss–Hermite quadrature (exact to ~1e-10 here), then bisection on s."""
    x, w = np.polynomial.hermite_e.hermegauss(96)
    w = w / w.sum()

    def hs_bounded(s: float) -> float:
        return 4.0 * math.sqrt(float(np.sum(w * depth_limit(s * x, 1.0)[0] ** 2)))

    lo, hi = SURF_HS_RATIO / 4.0, SURF_HS_RATIO / 2.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if hs_bounded(mid) < SURF_HS_RATIO else (lo, mid)
    return 4.0 * 0.5 * (lo + hi)


SURF_LINEAR_HS = _surf_linear_hs()  # Hs / h of the capped linear sea: 0.61


def surf_cap(hs, depth) -> np.ndarray:
    """The amplitude scale that keeps a linear sea of significant height hs (m) within the surf zone's
    SURF_LINEAR_HS·h over depth h (m): 1 where it is lower, 0 on dry land (h ≤ 0)."""
    depth = np.asarray(depth, dtype=np.float64)
    limit = SURF_LINEAR_HS * np.maximum(depth, 0.0)
    return np.where(depth > 0.0, np.minimum(1.0, limit / np.maximum(hs, 1e-300)), 0.0)


def shore_steepness(q: float, kh: np.ndarray) -> np.ndarray:
    return q + (max(Q_SHORE, q) - q) * (1.0 - np.tanh(kh))


@dataclass(frozen=True)
class Grid:
    """Regular grid: node (i, j) at origin + i·du·u + j·dv·v (ENU metres)."""

    origin: np.ndarray  # (2,) world xy of node (0, 0)
    u: np.ndarray  # (2,) unit
    v: np.ndarray  # (2,) unit
    du: float
    dv: float
    nu: int
    nv: int

    def nodes(self) -> np.ndarray:
        i = np.arange(self.nu)[:, None, None] * self.du * self.u
        j = np.arange(self.nv)[None, :, None] * self.dv * self.v
        return self.origin + i + j  # (nu, nv, 2)

    def to_grid(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Fractional node coordinates (clamped to the grid) of world points (..., 2)."""
        d = xy - self.origin
        gu = np.clip((d @ self.u) / self.du, 0.0, self.nu - 1)
        gv = np.clip((d @ self.v) / self.dv, 0.0, self.nv - 1) if self.nv > 1 else np.zeros(d.shape[:-1])
        return gu, gv


def _unit(azimuth_deg: float) -> np.ndarray:
    a = math.radians(azimuth_deg)
    return np.array([math.sin(a), math.cos(a)])


def load_map(name: str) -> np.ndarray:
    """Grey levels in [0, 1] of a bathymetry asset, row 0 at the image's top."""
    from PIL import Image

    from ..assets import resolve_asset

    path = resolve_asset("bathymetry", name, (".png",))
    with Image.open(path) as image:
        if image.width * image.height > 4096 * 4096:
            raise ValueError(f"bathymetry map {name!r} is larger than 4096x4096 pixels")
        grey = np.asarray(image.convert("I;16") if image.mode in ("I;16", "I", "I;16B") else image.convert("L"))
    scale = 65535.0 if grey.dtype == np.uint16 or grey.max() > 255 else 255.0
    return grey.astype(np.float64) / scale


def _bilinear(img: np.ndarray, fx: np.ndarray, fy: np.ndarray) -> np.ndarray:
    h, w = img.shape
    fx, fy = np.clip(fx, 0, w - 1), np.clip(fy, 0, h - 1)
    x0, y0 = np.minimum(fx.astype(int), w - 2 if w > 1 else 0), np.minimum(fy.astype(int), h - 2 if h > 1 else 0)
    x1, y1 = np.minimum(x0 + 1, w - 1), np.minimum(y0 + 1, h - 1)
    tx, ty = fx - x0, fy - y0
    top = img[y0, x0] * (1 - tx) + img[y0, x1] * tx
    bottom = img[y1, x0] * (1 - tx) + img[y1, x1] * tx
    return top * (1 - ty) + bottom * ty


def depth_at(bathy: Bathymetry, xy: np.ndarray) -> np.ndarray:
    """Water depth (m, ≤ 0 on dry land) at world points (..., 2)."""
    xy = np.asarray(xy, dtype=np.float64)
    if bathy.type == "uniform":
        return np.full(xy.shape[:-1], bathy.depth)
    if bathy.type == "slope":
        s = xy @ _unit(bathy.shore_heading)
        return np.minimum(bathy.slope * (bathy.shore_distance - s), bathy.depth)
    grey = load_map_cached(bathy.map)
    right, up = _unit(bathy.map_heading + 90.0), _unit(bathy.map_heading)
    d = xy - np.asarray(bathy.map_center)
    w, h = bathy.map_size
    fx = ((d @ right) / w + 0.5) * grey.shape[1] - 0.5
    fy = (0.5 - (d @ up) / h) * grey.shape[0] - 0.5
    inside = (np.abs(d @ right) <= w / 2) & (np.abs(d @ up) <= h / 2)
    lo, hi = bathy.map_elevation
    elevation = lo + (hi - lo) * _bilinear(grey, fx, fy)
    return np.where(inside, -elevation, bathy.depth)


@lru_cache(maxsize=4)
def load_map_cached(name: str) -> np.ndarray:
    return load_map(name)


def bathymetry_grid(bathy: Bathymetry, longest_wavelength: float) -> Grid | None:
    if bathy.type == "uniform":
        return None
    if bathy.type == "slope":
        u = _unit(bathy.shore_heading)
        v = np.array([u[1], -u[0]])
        # From where waves start to feel the bottom (h = λ/2, or the offshore depth) to past the shore.
        feel = min(bathy.depth, 0.5 * longest_wavelength)
        start = bathy.shore_distance - feel / bathy.slope - 0.1 * longest_wavelength
        end = bathy.shore_distance + max(2.0, 0.02 * feel / bathy.slope)
        n = int(min(SLOPE_MAX_CELLS, max(64, math.ceil((end - start) / 0.25)))) + 1
        du = (end - start) / (n - 1)
        return Grid(start * u, u, v, du, 1.0, n, 1)
    w, h = bathy.map_size
    right, up = _unit(bathy.map_heading + 90.0), _unit(bathy.map_heading)
    margin = 0.1 * max(w, h)
    width, height = w + 2 * margin, h + 2 * margin
    cell = max(width, height) / (MAP_MAX_CELLS - 1)
    nu, nv = int(math.ceil(width / cell)) + 1, int(math.ceil(height / cell)) + 1
    width, height = (nu - 1) * cell, (nv - 1) * cell  # square cells (the eikonal sweep's stencil)
    origin = np.asarray(bathy.map_center) - right * width / 2 - up * height / 2
    return Grid(origin, right, up, cell, cell, nu, nv)


@dataclass(frozen=True)
class WaveField:
    """Per-wave fields on a grid: residual phase R, amplitude factor F, wave vector K; and Q(x)."""

    grid: Grid
    residual: np.ndarray  # (n, nu, nv) rad
    factor: np.ndarray  # (n, nu, nv)
    kvec: np.ndarray  # (n, nu, nv, 2) rad/m
    steepness: np.ndarray  # (nu, nv)
    depth: np.ndarray  # (nu, nv) m
    breaking: np.ndarray  # (nu, nv): 1 − breaking cap (0 unbroken, → 1 in the surf zone)


def reference_waves(waves: WaveSet, depth: float) -> WaveSet:
    """The wave set over the reference depth: k(ω, h_ref) and the shoaled amplitude A·K_s, within the
    surf zone's cap (``surf_cap``)."""
    k = wavenumber(waves.omega, depth)
    ks = np.sqrt(group_velocity(waves.omega, waves.k, np.inf) / group_velocity(waves.omega, k, depth))
    amplitude = waves.amplitude * ks
    amplitude = amplitude * surf_cap(4.0 * math.sqrt(0.5 * float(np.sum(amplitude**2))), depth)
    return WaveSet(waves.omega, k, waves.direction, amplitude, waves.phase)


def _march(k: np.ndarray, k_ref: np.ndarray, d_ref: np.ndarray, ds: float) -> tuple[np.ndarray, ...]:
    """March ψ along axis 1 of k (n, ns, nc) for waves whose reference wave vector has components
    (along, across) = k_ref·d_ref (n, 2), along ≥ 0, over a bottom that varies along axis 1 only (a
    plane beach): the across component is conserved. Returns (ψ - k_ref·x, along, across components)."""
    n, ns, nc = k.shape
    along = np.empty_like(k)
    across = np.empty_like(k)
    residual = np.empty_like(k)
    ka_ref, kc_ref = (k_ref[:, None] * d_ref[:, 0][:, None]), (k_ref[:, None] * d_ref[:, 1][:, None])
    r = np.zeros((n, nc))  # residual phase of the current row
    kc0 = np.broadcast_to(kc_ref, (n, nc))  # conserved across a plane beach (Snell)
    for j in range(ns):
        kj = k[:, j, :]
        ka = np.sqrt(np.maximum(kj**2 - kc0**2, (MIN_COS * kj) ** 2))
        norm = np.hypot(ka, kc0)  # = k unless the caustic guard acted
        ka, kc = ka * kj / norm, kc0 * kj / norm
        if j > 0:
            r = r + ds * (0.5 * (ka + along[:, j - 1, :]) - ka_ref)
        residual[:, j, :], along[:, j, :], across[:, j, :] = r, ka, kc
    return residual, along, across


def _eikonal_sweep(k: np.ndarray, h: float, psi: np.ndarray, active: np.ndarray, tol: float = 1e-9,
                   max_iter: int = 64) -> np.ndarray:
    """Fast sweeping (Zhao 2005) for |∇ψ| = k on a square grid of spacing h: Gauss–Seidel sweeps in the
    four diagonal orders with the Godunov upwind update, until a round changes no ψ by more than
    ``tol``. Vectorised over the waves (axis 0 of k, psi) and over each anti-diagonal i' + j' = d of a
    sweep order: in that order a node's upwind neighbours lie on the previous anti-diagonal, so
    updating a whole anti-diagonal at once IS the sequential Gauss–Seidel sweep. ``active`` (nu, nv):
    the nodes visited; a node whose k is +inf keeps its ψ (a Dirichlet value, or +inf: an obstacle).
    Returns the new ψ."""
    n, nu, nv = k.shape
    w = nv + 2
    pad = np.full((nu + 2, w, n), np.inf)  # node-major: a gather fetches n contiguous values
    pad[1:-1, 1:-1] = np.moveaxis(psi, 0, -1)
    flat = pad.reshape(-1, n)
    kh = np.moveaxis(k, 0, -1).reshape(-1, n) * h
    ii, jj = np.nonzero(active)
    orders = []
    for su in (1, -1):
        for sv in (1, -1):
            d = (ii if su > 0 else nu - 1 - ii) + (jj if sv > 0 else nv - 1 - jj)
            order = np.argsort(d, kind="stable")
            cuts = np.flatnonzero(np.diff(d[order])) + 1
            orders.append([((ii[o] + 1) * w + jj[o] + 1, kh[ii[o] * nv + jj[o]]) for o in np.split(order, cuts)])
            orders[-1] = [(p, f, f * f, 2.0 * f * f) for p, f in orders[-1]]
    with np.errstate(invalid="ignore"):
        for _ in range(max_iter):
            before = flat.copy()
            for diagonals in orders:
                for p, f, f2, f22 in diagonals:
                    a = np.minimum(flat[p - w], flat[p + w])  # upwind along u
                    b = np.minimum(flat[p - 1], flat[p + 1])  # upwind along v
                    d2 = a - b
                    d2 *= d2
                    # (ψ−a)² + (ψ−b)² = (k h)² where both neighbours are upwind (|a − b| < k h),
                    # else the one-sided ψ = min(a, b) + k h. NaN (∞ − ∞: nothing upwind) drops out in fmin.
                    two = np.subtract(f22, d2)
                    np.maximum(two, 0.0, out=two)
                    np.sqrt(two, out=two)
                    two += a
                    two += b
                    two *= 0.5
                    one = np.minimum(a, b)
                    one += f
                    np.fmin(flat[p], np.where(d2 >= f2, one, two), out=two)
                    flat[p] = two
            diff = before - flat
            if not np.any(np.isinf(diff)) and float(np.nanmax(diff, initial=0.0)) <= tol:
                break
    return np.moveaxis(pad[1:-1, 1:-1], -1, 0).copy()


def _eikonal_field(grid: Grid, k: np.ndarray, wet: np.ndarray, waves: WaveSet, hk: np.ndarray,
                   use_u: np.ndarray, along_c: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Phase over a 2D grid: the viscosity solution of |∇ψ| = k with ψ = k_ref·D·x on the inflow
    edges (the margin is at the reference depth, so there the plane wave is exact), dry land an
    obstacle. A ray march is multi-valued past caustics; this first-arrival solution is continuous,
    with |ψ_i − ψ_j| ≤ max(k_i, k_j)·Δ between neighbours, so |ΔR| ≤ (max k + k_ref)·Δ.
    Then the land (and any water no wave reaches) is filled by a second solve, the wet solution held
    fixed, at the land's own k(DRY_DEPTH): R stays continuous where the field's amplitude is 0."""
    x = grid.nodes() - grid.origin  # (nu, nv, 2)
    plane = waves.k[:, None, None] * np.einsum("nc,uvc->nuv", waves.direction, x)
    du_c, dv_c = waves.direction @ grid.u, waves.direction @ grid.v
    fixed = np.zeros(k.shape, dtype=bool)
    fixed[du_c > 0.0, 0, :] = True
    fixed[du_c < 0.0, -1, :] = True
    fixed[dv_c > 0.0, :, 0] = True
    fixed[dv_c < 0.0, :, -1] = True
    psi = np.where(fixed, plane, np.inf)
    # A node's own k at +inf holds it (min(ψ, +inf) = ψ): the Dirichlet edges, per wave, and the land.
    # One sweep over all waves at once; then the land and unreached water, the wet solution held.
    psi = _eikonal_sweep(np.where(fixed | ~wet[None], np.inf, k), grid.du, psi, ~np.all(fixed, axis=0) & wet)
    rest = ~np.isfinite(psi)
    if rest.any():
        psi = _eikonal_sweep(np.where(rest, k, np.inf), grid.du, psi, np.any(rest, axis=0))
    residual = psi - plane
    gu, gv = np.gradient(psi, grid.du, grid.dv, axis=(1, 2))  # ∇ψ in grid components
    norm = np.hypot(gu, gv)
    flat = norm <= 0.0
    safe = np.where(flat, 1.0, norm)
    cu = np.where(flat, du_c[:, None, None], gu / safe)  # unit ∇ψ (the reference direction if ∇ψ = 0)
    cv = np.where(flat, dv_c[:, None, None], gv / safe)
    kvec = (k * cu)[..., None] * grid.u + (k * cv)[..., None] * grid.v  # |K| = k along ∇ψ
    # Refraction factor as on the beach: cos θ from the grid axis closest to the reference direction.
    au = np.where(use_u, np.sign(along_c), 0.0)[:, None, None]
    av = np.where(use_u, 0.0, np.sign(along_c))[:, None, None]
    cos_ratio = np.abs(along_c)[:, None, None] / np.maximum(cu * au + cv * av, MIN_COS)
    return residual, kvec, cos_ratio


def wave_field(bathy: Bathymetry, waves: WaveSet, q: float, omega_p: float) -> WaveField | None:
    """The per-wave field over a non-uniform bathymetry (``waves``: the reference set, over h_ref)."""
    longest = 2.0 * math.pi / float(np.min(waves.k)) if waves.n else 100.0
    grid = bathymetry_grid(bathy, longest)
    if grid is None:
        return None
    h = depth_at(bathy, grid.nodes())  # (nu, nv)
    hk = np.maximum(h, DRY_DEPTH)
    k = wavenumber(waves.omega[:, None, None], hk[None])  # (n, nu, nv)
    du_comp, dv_comp = waves.direction @ grid.u, waves.direction @ grid.v
    if grid.nv > 1:
        # A map: the grid axis (±u or ±v) closest to each wave's direction is the refraction
        # factor's reference axis.
        use_u = np.abs(du_comp) >= np.abs(dv_comp)
        along_c = np.where(use_u, du_comp, dv_comp)
        residual, kvec, cos_ratio = _eikonal_field(grid, k, h > 0.0, waves, hk, use_u, along_c)
    else:
        # A plane beach: march along ±u (waves of each sense together); ψ − k_ref·(along distance)
        # is accumulated, the across part of k_ref·x is the reference's.
        residual, kvec, cos_ratio = np.zeros_like(k), np.zeros(k.shape + (2,)), np.ones_like(k)
        for sgn in (1.0, -1.0):
            idx = np.nonzero(np.where(du_comp >= 0.0, 1.0, -1.0) == sgn)[0]
            if idx.size == 0:
                continue
            kg = k[idx][:, ::-1] if sgn < 0 else k[idx]  # (g, ns, 1)
            d_ref = np.stack([np.abs(du_comp[idx]), dv_comp[idx]], axis=1)
            r, ka, kc = _march(kg, waves.k[idx], d_ref, grid.du)
            if sgn < 0:
                r, ka, kc = r[:, ::-1], ka[:, ::-1], kc[:, ::-1]
            residual[idx] = r
            kvec[idx] = (sgn * ka)[..., None] * grid.u + kc[..., None] * grid.v
            cos_ratio[idx] = np.abs(du_comp[idx])[:, None, None] / np.maximum(ka / np.maximum(k[idx], 1e-300),
                                                                             MIN_COS)
    cg_ref = group_velocity(waves.omega, waves.k, bathy.depth)
    cg = group_velocity(waves.omega[:, None, None], k, hk[None])
    factor = np.sqrt(cg_ref[:, None, None] / cg) * np.sqrt(cos_ratio)
    wet = h > 0.0
    hs_local = 4.0 * np.sqrt(0.5 * np.sum((waves.amplitude[:, None, None] * factor) ** 2, axis=0))
    cap = surf_cap(hs_local, h)
    factor = factor * cap[None]
    kp = wavenumber(omega_p, hk)
    steep = shore_steepness(q, kp * hk)
    return WaveField(grid, residual, factor, kvec, steep, h, np.where(wet, 1.0 - cap, 0.0))
