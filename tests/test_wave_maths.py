"""The sea's wave maths against references written here (igserver/water): the dispersion solve to float64
round-off as its docstring promises, the group velocity as dω/dk of the dispersion relation, and more
below per module. GL-free and fast: they are part of the mutation run's selection (scripts/mutation.sh)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from igserver.water.dispersion import G, group_velocity, solve_kh, wavenumber


def _bisect_kh(x: np.ndarray) -> np.ndarray:
    """y tanh y = x by 200 float64 bisection steps: the interval shrinks below one ulp of y."""
    lo, hi = np.zeros_like(x), np.maximum(np.sqrt(x), x) + 1.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        below = mid * np.tanh(mid) < x
        lo, hi = np.where(below, mid, lo), np.where(below, hi, mid)
    return 0.5 * (lo + hi)


def test_dispersion_solve_reaches_float64_round_off():
    """'Newton then converges quadratically, three steps give float64 round-off' (dispersion.py), over
    x = 1e-12 … 1e7. Bisection stops at a few ulps of y (the bracket halves until neighbouring floats);
    y tanh y near x is then flat to ~4 ulps: 1e-14 relative is over ten times that and a Newton step with a
    wrong derivative (linear convergence from the 1.5 % start) stays above 1e-9 after four steps."""
    x = np.geomspace(1e-12, 1e7, 4000)
    rel = np.abs(solve_kh(x) - _bisect_kh(x)) / _bisect_kh(x)
    assert rel.max() < 1e-14, (rel.max(), x[np.argmax(rel)])
    assert solve_kh(0.0) == 0.0


def test_float32_inputs_are_solved_in_float64():
    """Callers may hand float32 arrays (GPU readbacks, msgpack float32): the maths is float64 throughout, so
    the result equals the float64 one for the same (float32-representable) inputs."""
    x32 = np.geomspace(1e-6, 1e3, 200).astype(np.float32)
    assert np.array_equal(solve_kh(x32), solve_kh(x32.astype(np.float64)))
    omega32, depth32 = np.geomspace(0.05, 20.0, 50).astype(np.float32), np.float32(7.3)
    k = wavenumber(omega32, depth32)
    assert k.dtype == np.float64 and np.array_equal(k, wavenumber(omega32.astype(np.float64), float(depth32)))
    cg = group_velocity(omega32, k.astype(np.float32), depth32)
    assert cg.dtype == np.float64
    assert np.array_equal(cg, group_velocity(omega32.astype(np.float64), k.astype(np.float32).astype(np.float64), float(depth32)))


@pytest.mark.parametrize("depth", [0.5, 3.0, 20.0, 200.0, math.inf])
def test_group_velocity_is_domega_dk(depth):
    """c_g = dω/dk of ω(k) = √(g k tanh(k h)), by central differences (step 1e-5 k: truncation ~1e-10,
    round-off ~1e-11; bound 1e-8)."""
    omega = np.geomspace(0.05, 30.0, 60)
    k = wavenumber(omega, depth)

    def omega_of(kk):
        return np.sqrt(G * kk * (np.tanh(kk * depth) if math.isfinite(depth) else 1.0))

    dk = 1e-5 * k
    expected = (omega_of(k + dk) - omega_of(k - dk)) / (2 * dk)
    assert np.allclose(group_velocity(omega, k, depth), expected, rtol=1e-8, atol=0)


def test_group_velocity_limits():
    """Shallow water: c_g → √(g h) (non-dispersive) up to the (kh)² terms; deep: c_g = c/2 = g/(2ω)."""
    h, omega = 0.01, 0.05
    k = wavenumber(omega, h)
    assert k * h < 2e-3
    assert group_velocity(omega, k, h) == pytest.approx(math.sqrt(G * h), rel=(k * h) ** 2)
    assert group_velocity(3.0, wavenumber(3.0, math.inf), math.inf) == pytest.approx(G / 6.0, rel=1e-14)
