"""Halos of lights in fog: the single-scattered light of each point source along a pixel's view
ray, from one table lookup per end of the ray instead of a quadrature per pixel.

For a light at distance h from the view ray whose closest point is t0 along it, the sample at
angle psi seen from the light (s = t0 + h tan psi along the ray, r = h / cos psi from the light)
has travelled s + r = t0 + h T(psi), T(psi) = tan(psi/2 + pi/4), so in a homogeneous medium
(extinction beta, albedo omega, Henyey-Greenstein g; scattering cosine sin psi)
    L = omega beta I / h  exp(-beta t0)  [H(phi0, a) - H(phi1, a)],   a = beta h,
    H(phi, a) = integral_{phi}^{pi/2} p_g(sin psi) exp(-a T(psi)) dpsi,
phi0 = atan(-t0, h) at the camera, phi1 = atan(D - t0, h) at the surface (Sun et al. 2005 do the
same for an isotropic medium). H depends on (phi, a, g) only: one 3D table per process, filled in
float64 here. It spans hundreds of decades, so the table holds K = log H + a T(phi), a smooth
function of moderate size, and since beta t0 + a T(phi) is beta times the path camera -> point
-> light, each end becomes exp(K - beta * path): at the camera the path is the light's distance
d, at the surface D + r1. No term overflows, whatever side of the camera the light is on.

The table's phi axis is u = T(phi) / (1 + T(phi)) (nodes uniform in u): an end of the ray at signed
distance s along it from the light's closest point and r from the light has T = (s + r) / h, so
    u = 1 - h / (r + |s| + h)  (s >= 0),   u = h / (r + |s| + h)  (s < 0)
with no cancellation and no inverse tangent (halos.frag.glsl). du/dphi = 1 / (2 (sin x + cos x)^2),
x = phi/2 + pi/4, lies in [1/4, 1/2]: the nodes are 0.64x as far apart in phi as uniform ones at
both ends (the HG forward peak is at phi = pi/2) and 1.27x in the middle.
"""

from __future__ import annotations

import math
from functools import lru_cache

import moderngl
import numpy as np

from ..bindings import use_texture

N_PHI = 256  # nodes over u in [0, 1] (phi in [-pi/2, pi/2])
N_A = 64  # nodes of log10(a) over [A_LOG_MIN, A_LOG_MAX]
A_LOG_MIN, A_LOG_MAX = -5.0, 3.0  # a = beta h below 1e-5: H no longer depends on a; above 1e3: exp(-a) is 0
# The fog model's asymmetry (render/sky/haze.py: g = 0.7 + 0.15 fog, fog in [0, 1]) spans this range.
G_MIN, G_MAX = 0.7, 0.85
N_G = 16
_GAUSS_X, _GAUSS_W = np.polynomial.legendre.leggauss(6)


def hg(g: float | np.ndarray, c: np.ndarray) -> np.ndarray:
    return (1.0 - g * g) / (4.0 * math.pi * np.maximum(1.0 + g * g - 2.0 * g * c, 1e-12) ** 1.5)


def path_factor(psi: np.ndarray) -> np.ndarray:
    """T(psi) = tan psi + sec psi = tan(psi/2 + pi/4)."""
    return np.tan(0.5 * psi + 0.25 * math.pi)


def phi_of_u(u: np.ndarray) -> np.ndarray:
    """The table's phi axis: u = T / (1 + T), T(phi) = tan(phi/2 + pi/4)."""
    return 2.0 * np.arctan2(u, 1.0 - u) - 0.5 * math.pi


def u_of_phi(phi: np.ndarray) -> np.ndarray:
    x = 0.5 * phi + 0.25 * math.pi
    return np.sin(x) / (np.sin(x) + np.cos(x))


def axes() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    phi = phi_of_u(np.linspace(0.0, 1.0, N_PHI))
    a = 10.0 ** np.linspace(A_LOG_MIN, A_LOG_MAX, N_A)
    g = np.linspace(G_MIN, G_MAX, N_G)
    return phi, a, g


def build_table() -> np.ndarray:
    """(N_G, N_A, N_PHI) float64: K = log H + a T(phi) at the nodes. H by 6-point Gauss-Legendre
    per cell, summed from pi/2 down in the log domain (no underflow)."""
    phi, a, g = axes()
    lo, hi = phi[:-1], phi[1:]
    psi = 0.5 * (lo + hi)[:, None] + 0.5 * (hi - lo)[:, None] * _GAUSS_X[None, :]  # (cells, 6)
    w = 0.5 * (hi - lo)[:, None] * _GAUSS_W[None, :]
    log_f = (np.log(hg(g[:, None, None, None], np.sin(psi)[None, None]))
             - a[None, :, None, None] * path_factor(psi)[None, None] + np.log(w)[None, None])
    peak = log_f.max(axis=-1, keepdims=True)
    log_cells = peak[..., 0] + np.log(np.sum(np.exp(log_f - peak), axis=-1))  # (g, a, cells)
    log_h = np.logaddexp.accumulate(log_cells[..., ::-1], axis=-1)[..., ::-1]  # H at the nodes 0..N-2
    k = log_h + a[None, :, None] * path_factor(phi[:-1])[None, None, :]
    # At phi = pi/2 H is 0 and T infinite: the last node holds the one before it and is never read
    # (lookups in the tail go through its first node: TAIL below).
    return np.concatenate([k, k[..., -1:]], axis=-1)


# The tail, phi in [PHI_TAIL, pi/2] (the light nearly straight behind the ray's end). With
# eps = pi/2 - phi small, T(psi) ~ 2 / (pi/2 - psi) and p_g(sin psi) ~ p_g(1) there; with
# psi = pi/2 - eps u:
#   H(phi, a) ~ eps p_g(1) integral_0^1 exp(-(2 a / eps) / u) du,   K = log H + a T ~ log eps + F(a / eps),
# so K(phi, a) = K(PHI_TAIL, a / ratio) + log(ratio), ratio = eps / TAIL: the tail's first node at a
# scaled a. The shader takes ratio = T(PHI_TAIL) / T(phi) = tan(eps/2) / tan(TAIL/2) (within
# TAIL^2 / 12 = 3e-4 of eps / TAIL), which is h / h_eff with h_eff = max(h, (s + r) / T(PHI_TAIL)):
# the lookup's a is beta h_eff, and exp(K) = ratio exp(K(PHI_TAIL, beta h_eff)) takes no logarithm.
# K ~ log eps is far from linear there: linear interpolation was 9-13 % low one degree from the
# light's antipode, and the linear continuation to pi/2 6x high within 0.1 deg of it (a bright dot
# opposite a fire behind the camera). The tail's other nodes are not read.
U_TAIL = 1.0 - 4.0 / (N_PHI - 1)  # four cells
T_TAIL = U_TAIL / (1.0 - U_TAIL)  # T(PHI_TAIL)
PHI_TAIL = float(phi_of_u(U_TAIL))  # pi/2 - 1.8 deg
TAIL = 0.5 * math.pi - PHI_TAIL


def tail_ratio(phi: np.ndarray) -> np.ndarray:
    """T(PHI_TAIL) / T(phi) in the tail, 1 before it (halos.frag.glsl: h / h_eff)."""
    return np.clip(T_TAIL / np.maximum(path_factor(np.minimum(phi, 0.5 * math.pi)), 1e-300), 1e-30, 1.0)


_TABLE: np.ndarray | None = None


def table() -> np.ndarray:
    global _TABLE
    if _TABLE is None:
        _TABLE = build_table()
    return _TABLE


@lru_cache(maxsize=8)
def _slice64(g: float) -> np.ndarray:
    """(N_A, N_PHI) float64, read-only: K at g, linear between the table's g nodes."""
    z = (min(max(g, G_MIN), G_MAX) - G_MIN) / (G_MAX - G_MIN) * (N_G - 1)
    i = min(int(z), N_G - 2)
    k = (1.0 - (z - i)) * table()[i] + (z - i) * table()[i + 1]
    k.setflags(write=False)
    return k


def lookup(phi: np.ndarray, a: np.ndarray, g: float) -> np.ndarray:
    """K at arrays of (phi, a), as the GPU's lookup (clamped to the table's range): bilinear in the
    slice at g, which is linear between the table's g nodes (trilinear in the table)."""
    t = _slice64(g)
    ratio = tail_ratio(phi)
    x = np.clip(u_of_phi(np.minimum(phi, PHI_TAIL)) * (N_PHI - 1), 0.0, N_PHI - 2.0)
    y = np.clip((np.log10(np.maximum(a, 1e-30) / ratio) - A_LOG_MIN) / (A_LOG_MAX - A_LOG_MIN) * (N_A - 1), 0.0, N_A - 1.0)
    i, j = np.minimum(x.astype(np.int64), N_PHI - 2), np.minimum(y.astype(np.int64), N_A - 2)
    fx, fy = x - i, y - j
    return ((1.0 - fy) * ((1.0 - fx) * t[j, i] + fx * t[j, i + 1])
            + fy * ((1.0 - fx) * t[j + 1, i] + fx * t[j + 1, i + 1])) + np.log(ratio)


def table_slice(g: float) -> np.ndarray:
    """(N_A, N_PHI) float32: K at the frame's g (the texture HaloTable holds)."""
    return np.ascontiguousarray(_slice64(g).astype(np.float32))


class HaloTable:
    """The table's slice at the frame's g as an R32F 2D texture (x: phi, y: log10 a), bilinear;
    rewritten only when g changes (a 2D lookup costs a fraction of a 3D one on llvmpipe)."""

    def __init__(self, ctx: moderngl.Context):
        self.texture = ctx.texture((N_PHI, N_A), 1, dtype="f4")
        self.texture.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self.texture.repeat_x = self.texture.repeat_y = False
        self.g: float | None = None

    def use(self, g: float, unit: int) -> None:
        if g != self.g:
            self.texture.write(table_slice(g).tobytes())
            self.g = g
        use_texture(self.texture, unit)

    def release(self) -> None:
        self.texture.release()


def _lookup(phi: float, a: float, g: float) -> float:
    return float(lookup(np.asarray(phi, dtype=np.float64), np.asarray(a, dtype=np.float64), g))


def halo_from_table(t0: float, h: float, D: float, beta: float, g: float) -> float:
    """The factor exp(-beta t0) [H(phi0) - H(phi1)] of one light as tonemap.glsl evaluates it (numpy
    mirror, for tests): times omega beta I / h it is the halo's radiance."""
    a = beta * h
    phi0, phi1 = math.atan2(-t0, h), math.atan2(D - t0, h)
    if phi1 <= phi0:
        return 0.0
    d = math.hypot(t0, h)  # camera to light
    r1 = math.hypot(D - t0, h)  # surface point to light
    return max(math.exp(_lookup(phi0, a, g) - beta * d) - math.exp(_lookup(phi1, a, g) - beta * (D + r1)), 0.0)


def halo_bound(angle: np.ndarray, d: float, beta: float, g: float) -> np.ndarray:
    """An upper bound of halo_from_table's factor over every surface distance D, for a view ray at
    ``angle`` (rad) from the direction of a light at distance d: the far end's term is never
    negative, so the factor is at most exp(K(phi0, beta h) - beta d), which does not depend on D.
    Times omega beta I / h it bounds the halo's radiance along every ray on the cone of that angle
    (h = d sin angle, floored as the shader floors it)."""
    angle = np.asarray(angle, dtype=np.float64)
    t0 = d * np.cos(angle)
    h = np.maximum(d * np.sin(angle), 0.05)
    return np.exp(lookup(np.arctan2(-t0, h), beta * h, g) - beta * d)


# Angles from a light's direction where halo_radius evaluates the bound: 1 deg steps, and under
# 1 deg geometric steps down to 1 microradian (a bright light's halo may be a sharp peak around it).
_ANGLES = np.concatenate([np.geomspace(1e-6, math.radians(1.0), 48)[:-1], np.linspace(0.0, math.pi, 181)[1:]])


def halo_radius(d: float, beta: float, omega: float, g: float, intensity: float, threshold: float,
                pixel_angle: float = 0.0) -> float:
    """The angle (rad) around a light's direction outside which its halo's radiance (intensity cd,
    the brightest channel) stays under ``threshold`` (cd/m^2) on every view ray: the next node of
    _ANGLES after the last one where halo_bound's radiance reaches it (the bound is smooth between
    nodes); 0 when it nowhere does, pi when the whole sphere may show the halo. Nearer the light
    than half a ``pixel_angle`` (rad) the halo is the light's own pixel: the bound is taken there
    (about half the halo's mean over that pixel: its 1 / angle core averages to twice the rim's)."""
    h, bound = _halo_profile(d, beta, g, pixel_angle)
    radiance = omega * beta * intensity / h * bound
    above = np.nonzero(radiance >= threshold)[0]
    if len(above) == 0:
        return 0.0
    return float(_ANGLES[min(above[-1] + 1, len(_ANGLES) - 1)])


@lru_cache(maxsize=64)
def _halo_profile(d: float, beta: float, g: float, pixel_angle: float) -> tuple[np.ndarray, np.ndarray]:
    """halo_radius's distances h (m) of the view rays from the light and halo_bound at _ANGLES:
    what does not depend on the light's intensity (which flickers) or the exposure, kept per exact
    (d, beta, g, pixel_angle) while the camera, the light and the fog stay put."""
    angles = np.maximum(_ANGLES, 0.5 * pixel_angle)
    h = np.maximum(d * np.sin(angles), 0.05)
    bound = halo_bound(angles, d, beta, g)
    h.flags.writeable = bound.flags.writeable = False
    return h, bound


_NODES: dict[int, tuple[np.ndarray, np.ndarray]] = {}


def _leggauss(n: int) -> tuple[np.ndarray, np.ndarray]:
    if n not in _NODES:
        _NODES[n] = np.polynomial.legendre.leggauss(n)
    return _NODES[n]


def halo_reference(t0: float, h: float, D: float, beta: float, g: float, n: int = 4096) -> float:
    """The same factor by direct quadrature along the ray in phi (float64, n Gauss-Legendre nodes)."""
    phi0, phi1 = math.atan2(-t0, h), math.atan2(D - t0, h)
    if phi1 <= phi0:
        return 0.0
    x, w = _leggauss(n)
    phi = 0.5 * (phi0 + phi1) + 0.5 * (phi1 - phi0) * x
    s = t0 + h * np.tan(phi)
    r = h / np.cos(phi)
    f = hg(g, np.sin(phi)) * np.exp(-np.minimum(beta * (s + r), 700.0))
    return float(0.5 * (phi1 - phi0) * np.sum(w * f))


def table_uniforms(beta: float) -> dict:
    """Map of halos.frag.glsl's lookups from (u, log2 h_eff) to texture coordinates (node i at
    texel centre (i + 0.5) / N; log10 a = log10 beta + log2 h_eff log10 2), and the tail's start."""
    a_span = A_LOG_MAX - A_LOG_MIN
    y_scale = (N_A - 1) / (a_span * N_A)
    return {"u_halo_table_map": ((N_PHI - 1) / N_PHI, 0.5 / N_PHI, y_scale * math.log10(2.0),
                                 ((math.log10(beta) - A_LOG_MIN) / a_span * (N_A - 1) + 0.5) / N_A),
            "u_halo_tail": (U_TAIL, 1.0 / T_TAIL)}
