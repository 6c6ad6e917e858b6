"""Linear dispersion ω² = g k tanh(k h), solved for k by Newton from an explicit start.

Dimensionless form: with x = k₀h = ω²h/g (the deep-water wavenumber times depth) and y = k h,
solve  f(y) = y tanh(y) − x = 0.  Start: Fenton & McKee's explicit approximation
y₀ = x / tanh(x^¾)^(⅔) (within 1.5 % for all x); Newton then converges quadratically, three steps
give float64 round-off. f'(y) = tanh y + y sech² y, with sech² y written as 4e/(1+e)², e = exp(−2y),
which underflows gracefully to 0 for large y instead of overflowing cosh (docs/design.md#stability). Everything
stays finite from x = 1e-12 (a 1 mm puddle under a long swell) to x = 1e7 (11 km under a ripple).
"""

from __future__ import annotations

import numpy as np

G = 9.80665  # m/s², standard gravity
NEWTON_STEPS = 4


def _sech2(y: np.ndarray) -> np.ndarray:
    e = np.exp(-2.0 * y)
    return 4.0 * e / (1.0 + e) ** 2


def solve_kh(x) -> np.ndarray:
    """y = k h solving y tanh y = x (x = ω² h / g ≥ 0), elementwise, float64."""
    x = np.asarray(x, dtype=np.float64)
    xs = np.maximum(x, 1e-300)
    y = xs / np.tanh(xs**0.75) ** (2.0 / 3.0)
    for _ in range(NEWTON_STEPS):
        t = np.tanh(y)
        f = y * t - xs
        df = t + y * _sech2(y)
        y = y - f / df
    return np.where(x > 0.0, y, 0.0)


def wavenumber(omega, depth) -> np.ndarray:
    """k (rad/m) of angular frequency ω (rad/s) over depth h (m; np.inf for deep water)."""
    omega = np.asarray(omega, dtype=np.float64)
    depth = np.asarray(depth, dtype=np.float64)
    k_deep = omega**2 / G
    finite = np.isfinite(depth)
    h = np.where(finite, np.maximum(depth, 1e-300), 1.0)
    k = solve_kh(k_deep * h) / h
    return np.where(finite, k, k_deep)


def group_velocity(omega, k, depth) -> np.ndarray:
    """c_g = (ω/k)·(1 + 2kh/sinh 2kh)/2 (m/s), with 2kh/sinh 2kh → 1 as kh → 0 and → 0 as kh → ∞."""
    omega, k, depth = (np.asarray(a, dtype=np.float64) for a in (omega, k, depth))
    kh = np.where(np.isfinite(depth), k * depth, np.inf)
    two = 2.0 * np.minimum(kh, 400.0)
    # 2kh/sinh(2kh) = 4kh e^{-2kh} / (1 - e^{-4kh}); series 1 - (2kh)²/6 for small kh.
    small = two < 1e-4
    safe = np.where(small, 1.0, two)
    ratio = np.where(small, 1.0 - two**2 / 6.0, 2.0 * safe * np.exp(-safe) / -np.expm1(-2.0 * safe))
    return 0.5 * (omega / np.maximum(k, 1e-300)) * (1.0 + ratio)
