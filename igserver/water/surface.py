"""The displaced sea surface: the one evaluation the shader mirrors and the host queries call.

For a rest point p₀ (world ENU x, y; float64) and wave i:
    θ_i = k_i D_i·p₀ + R_i(p₀) − ω_i t + φ_i            (R: residual phase over the bathymetry)
    a_i = A_i F_i(p₀)                                    (F: shoaling · refraction · breaking)
    b_i = min(Q(p₀) / (|K_i| n), a_i)                    (horizontal amplitude: Q_i A_i, Q_i = Q/(ω_i A_i n),
                                                          never more than the vertical: no loops)
    z₁ = Σ a_i sin θ_i,   z₂ = ½(X² + Y² − Σ s_i²),   X + iY = Σ s_i e^{iθ_i},   s_i = a_i √(α |K_i|)
    P = (p₀ + Σ b_i K̂_i cos θ_i,  L(z₁ + z₂))          (L: the depth limit, bathymetry.depth_limit)
with K_i(p₀) the local wave vector (k_i D_i in uniform depth). Tangents ignore the slow variation of
a, b and K over a wavelength: ∂P/∂p₀ = I − Σ b_i K̂_i K_iᵀ sin θ_i (2×2, horizontal) and
∂z/∂p₀ = L′·(Σ a_i K_i cos θ_i + X ∇X + Y ∇Y). The horizontal Jacobian J = det(I − M) with
‖M‖ ≤ Σ b_i|K_i| ≤ Q ≤ 1, so J ≥ 0: the surface never folds over (z₂ and L are vertical only).

Crests sharper than troughs (z₂). Seen at a fixed place (Eulerian), the Gerstner sea is, to second
order in steepness, η = z₁ − Δ·∇z₁. For a narrow band (one k, b = a) Δ·∇z₁ = k ẑ₁² (ẑ₁ = −Σ a_i cos θ_i,
the Hilbert transform of z₁), so η = z₁ + ½k(z₁² − ẑ₁²) − ½k(z₁² + ẑ₁²): Stokes's second order (the
sum-frequency waves that raise crests and flatten troughs; Longuet-Higgins 1963, Tayfun 1980:
skewness λ₃ = 3σk) plus a set-down ½k|A|² under every wave group (|A|² = z₁² + ẑ₁²) whose covariance
with z₁² cancels λ₃ exactly: a many-wave Gerstner sea has height skewness 0 (for any b ≤ a). The
vertical correction z₂ = ½αk(z₁² + ẑ₁²) at the rest point (to this order, the second-order Lagrangian
mean level of the wave groups: Pierson 1961, Fouques et al. 2006) undoes the set-down; at a fixed place
what remains is Stokes's second order, λ₃ = 3ασk. Over a spectrum k z₁² becomes |Σ a_i √k_i e^{iθ_i}|²
(the kernel √(k_i k_j), exact for equal wavenumbers): two more sums per point (X, Y), not one per pair
of waves. α (``second_order``) carries what that narrow-band kernel misses, the spectrum's width
(``spectrum.second_order_coefficient``). ½ Σ s_i² is z₂'s mean: subtracted, the sea's mean level is
what it was. The horizontal map is untouched: J, the foam and the queries' inversion are as before.

A host asks for the height at a WORLD point x: the rest point p₀ with p₀ + Δ(p₀) = x is found by
Chebyshev's method (Newton plus the second-order term) on that 2×2 map (unique while J > 0), then P,
the normal and the velocity dP/dt at p₀ (``query``).

Time: ω_i t + (k_i D_i·origin) is reduced modulo 2π in float64 here (``phase_offsets``), so the GPU
only sees phases in [0, 2π) and a camera-relative position: the sea at t = 1e9 s looks like at 100 s.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from functools import cached_property, lru_cache

import numpy as np

from ..scene.model import Ocean, Weather
from .bathymetry import WaveField, reference_waves, shore_steepness, wave_field
from .dispersion import wavenumber
from .field_sampling import _field_nodes, _interpolate
from .spectrum import (SeaSpectrum, WaveSet, calibrate_detail, sea_spectrum, second_order_coefficient,
                       wave_bands)
from .wave_sums import N_COS, N_SIN, _answer, _chebyshev_step, _outputs, _weights
from .workspace import _Work, _workspace

DETAIL_WAVES = 36  # waves in the normal-map band
TWO_PI = 2.0 * math.pi
# Chebyshev updates at most. Two reach ~1e-9 m in uniform depth; over a height map the phase has kinks
# where two first arrivals meet (an island's lee): there the interpolated K is an average of the two
# branches' and the convergence is linear (~0.5 per update, island test), so a few points need ~13.
# Points that converged leave the loop, so the extra updates cost only those.
NEWTON_STEPS = 14
QUERY_CHUNK = 1 << 17  # points x waves per chunk of a query (uniform depth; half that over a bathymetry)


def whitecap_coverage(wind: float) -> float:
    """Fraction of the sea white with whitecaps, Monahan & O'Muircheartaigh (1980): W = 3.84e-6·U^3.41
    (U the 10 m wind, m/s; 1.8 % at 12 m/s, 16 % at 22.6), held at one half past 31.6 m/s."""
    return min(3.84e-6 * max(wind, 0.0) ** 3.41, 0.5)


@dataclass(frozen=True)
class SeaSurface:
    spectrum: SeaSpectrum
    waves: WaveSet  # mesh band over the reference depth (k = k(ω, h_ref), A shoaled to h_ref)
    detail: WaveSet  # normal-map band, deep water
    field: WaveField | None  # per-wave fields over a non-uniform bathymetry
    steepness: float  # Q over the reference depth
    reference_depth: float  # m: also the depth limit's h in uniform depth (over a field: its depth)
    second_order: float = 0.0  # α of the crest-trough asymmetry z₂ (module docstring); 0: linear Gerstner

    @property
    def n(self) -> int:
        return self.waves.n

    @property
    def amplitude_sum(self) -> float:
        """Σ A_i·max F: radius of the error sphere (the largest displacement the mesh can show)."""
        fmax = float(np.max(self.field.factor)) if self.field is not None and self.n else 1.0
        return float(np.sum(self.waves.amplitude)) * max(fmax, 1.0)

    @cached_property
    def jacobian_samples(self) -> np.ndarray:
        """J of the mesh waves at 12,000 points: 4000 over 1 km², 3 instants (fixed: deterministic)."""
        xy = np.random.default_rng(11).uniform(-500.0, 500.0, (4000, 2))
        return np.concatenate([self.evaluate(xy, t, full=False)["jacobian"] for t in (0.0, 7.3, 19.1)])

    def foam_jacobian(self, wind: float) -> float:
        """J below which the surface counts as whitecap: the quantile of J (``jacobian_samples``) at
        Monahan & O'Muircheartaigh's (1980) whitecap coverage (``whitecap_coverage``)."""
        coverage = whitecap_coverage(wind)
        if coverage <= 0.0 or self.n == 0:
            return -1.0
        return float(np.quantile(self.jacobian_samples, coverage))

    def phase_offsets(self, t: float, origin_xy=(0.0, 0.0)) -> np.ndarray:
        """(k_i D_i·origin − ω_i t + φ_i) mod 2π, float64: the GPU adds k_i D_i·(p − origin)."""
        o = np.asarray(origin_xy, dtype=np.float64)
        spatial = np.mod(self.waves.k * (self.waves.direction @ o), TWO_PI)
        temporal = np.mod(self.waves.omega * float(t), TWO_PI)
        return np.mod(spatial - temporal + self.waves.phase, TWO_PI)

    # ---- the wave sums (arrays wave-major: (n waves, N points), each row contiguous) ----------------
    @cached_property
    def _kd(self) -> np.ndarray:
        return self.waves.k[:, None] * self.waves.direction  # (n, 2) reference wave vectors

    @cached_property
    def _kd32(self) -> np.ndarray:
        return self._kd.astype(np.float32)

    @cached_property
    def _uniform_weights(self) -> tuple:
        """Uniform depth: the per-wave weights of every wave sum (see ``_weights``), (13, n) for the
        cosines and (10, n) for the sines: each set of sums is then one BLAS product; z₂'s mean and
        the depth limit's h."""
        w = self.waves
        kx, ky = w.k * w.direction[:, 0], w.k * w.direction[:, 1]
        b = np.minimum(self.steepness / (np.maximum(w.k, 1e-300) * max(w.n, 1)), w.amplitude)
        wc, ws, mu = _weights(w.amplitude, kx, ky, b / np.maximum(w.k, 1e-300), w.omega, w.k, self.second_order)
        return wc, ws, float(mu), self.reference_depth

    def _field_at(self, p0: np.ndarray, w: "_Work") -> tuple[np.ndarray, tuple]:
        """Over a bathymetry: residual phase R (n, N) and the per-point sum weights (13, n, N) cosine,
        (10, n, N) sine, z₂'s mean (N,) and the depth (N,) at rest points p0 (N, 2) — the field
        interpolated as the shader does."""
        n, f, m = self.waves.n, self.field, len(p0)
        gu, gv = f.grid.to_grid(p0)
        v = _interpolate(_field_nodes(f), f.residual.shape[1:], gu, gv, w)  # (4n + 2, N): R, F, Kx, Ky per wave, Q, h
        kx, ky = v[2 * n:3 * n], v[3 * n:4 * n]
        kmag = np.multiply(kx, kx, out=w.get("kmag", (n, m)))  # |K| (np.hypot is ~50x slower here)
        kmag += np.multiply(ky, ky, out=w.get("a", (n, m)))
        np.sqrt(kmag, out=kmag)
        np.maximum(kmag, 1e-300, out=kmag)
        a = np.multiply(v[n:2 * n], self.waves.amplitude[:, None], out=w.get("a", (n, m)))
        bk = np.multiply(kmag, max(n, 1), out=w.get("bk", (n, m)))
        np.divide(v[4 * n:4 * n + 1], bk, out=bk)
        np.minimum(bk, a, out=bk)
        bk /= kmag  # b / |K|, with b = min(Q / (|K| n), a)
        wc, ws, mu = _weights(a, kx, ky, bk, self.waves.omega[:, None], kmag, self.second_order, w)
        return v[:n], (wc, ws, mu, v[4 * n + 1].copy())

    def _phases(self, p0: np.ndarray, o: np.ndarray, offsets: np.ndarray, w: "_Work"):
        """sin, cos (float32, (n, N)) of the phases at rest points p0 (N, 2), the residual phase R (or
        None) and the sum weights."""
        theta = np.matmul(self._kd, (p0 - o).T, out=w.get("theta", (self.n, len(p0))))
        theta += offsets[:, None]
        if self.field is None:
            r, weights = None, self._uniform_weights
        else:
            r, weights = self._field_at(p0, w)
            theta += r
        s, c = _sincos(theta, w)
        return s, c, r, weights

    def _sums(self, s: np.ndarray, c: np.ndarray, weights, w: "_Work") -> tuple[np.ndarray, np.ndarray]:
        """Every wave sum at once: Σ_i cos θ_i · wc_i (13, N) and Σ_i sin θ_i · ws_i (10, N) (float64
        products of the float32 sines and cosines)."""
        wc, ws = weights[:2]
        c64, s64 = w.get("c64", c.shape), w.get("s64", s.shape)
        np.copyto(c64, c)
        np.copyto(s64, s)
        m = c.shape[1]
        cs, ss = w.get("cs", (N_COS, m)), w.get("ss", (N_SIN, m))
        if wc.ndim == 2:  # uniform: one (9, n) @ (n, N) product each
            return np.matmul(wc, c64, out=cs), np.matmul(ws, s64, out=ss)
        return np.einsum("jnp,np->jp", wc, c64, out=cs), np.einsum("jnp,np->jp", ws, s64, out=ss)

    def evaluate(self, p0, t: float, origin_xy=(0.0, 0.0), full: bool = True) -> dict:
        """Displaced point, tangent frame and velocity at rest points p0 (N, 2) world xy.

        With ``full`` False only the horizontal displacement and its Jacobian. Vectorised over points x
        waves: the phases in float64, reduced, then sin/cos in float32 and every sum over the waves one
        product with a matrix of per-wave weights (``_sums``)."""
        p0 = np.atleast_2d(np.asarray(p0, dtype=np.float64))
        o = np.asarray(origin_xy, dtype=np.float64)
        w = _Work()
        s, c, _, weights = self._phases(p0, o, self.phase_offsets(t, o), w)
        return _outputs(p0, *self._sums(s, c, weights, w), full, *weights[2:])

    def query(self, xy, t: float, tolerance: float = 1e-5) -> dict:
        """Height, normal and velocity of the surface ABOVE world points xy (N, 2): inverts Δ by
        Chebyshev's method (Newton plus the second-order term; J ≥ 1 − Q keeps it well posed) to
        ``tolerance`` m horizontally — in uniform depth two updates reach ~1e-9 m from the start p₀ = x.

        The phases at x are reduced in float64 once; an iterate p = x + δ only needs sin/cos of the
        small K·δ (float32) and the angle-addition products, not a fresh float64 reduction. Points go in
        chunks through reused buffers (no fresh pages per call)."""
        x = np.atleast_2d(np.asarray(xy, dtype=np.float64))
        n = len(x)
        o = np.mean(x, axis=0) if n else np.zeros(2)
        offsets = self.phase_offsets(t, o)
        out = {"height": np.zeros(n), "normal": np.zeros((n, 3)), "velocity": np.zeros((n, 3)),
               "residual": np.zeros(n), "rest": x.copy()}
        chunk = max(64, (QUERY_CHUNK if self.field is None else QUERY_CHUNK // 2) // max(self.n, 1))
        with _workspace() as w:
            for lo in range(0, n, chunk):
                part = {k: v[lo:lo + chunk] for k, v in out.items()}
                self._query_chunk(x[lo:lo + chunk], o, offsets, tolerance, w, part)
        return out

    def _query_chunk(self, x: np.ndarray, o: np.ndarray, offsets: np.ndarray, tolerance: float, w: "_Work",
                     out: dict) -> None:
        n = self.n
        s0, c0, r0, weights = self._phases(x, o, offsets, w)  # at x (s0, c0 in the "a" buffers)
        if r0 is not None:  # a view of the interpolation buffer: kept apart from the next iterate's
            r0 = np.copyto(w.get("r0a", r0.shape), r0) or w.get("r0a", r0.shape)
        s, c, tag = s0, c0, "a"
        xa = np.ascontiguousarray(x.T)  # (2, N): coordinate-major, like the sums
        active, p = np.arange(len(x)), xa.copy()
        for step in range(NEWTON_STEPS + 1):
            cs, ss = self._sums(s, c, weights, w)
            err = p + cs[:2]
            err -= xa
            size = np.maximum(np.abs(err[0]), np.abs(err[1]))
            done = size <= tolerance
            if step == NEWTON_STEPS:
                done[:] = True
            n_done = int(np.count_nonzero(done))
            if n_done:
                every = n_done == len(done)
                pick = (lambda a: a) if every else (lambda a: a[..., done])
                idx = active if every else active[done]
                mu, depth = (x if np.ndim(x) == 0 else pick(x) for x in weights[2:])
                _answer(pick(cs), pick(ss), out, idx, mu, depth)
                out["residual"][idx], out["rest"][idx] = pick(size), pick(p).T
                if every:
                    break
                more = ~done
                active, xa, p, err, cs, ss = active[more], xa[:, more], p[:, more], err[:, more], cs[:, more], ss[:, more]
                tag = "b" if tag == "a" else "a"  # compact the per-point state (ping-pong buffers)
                m = len(active)
                s0 = np.compress(more, s0, axis=1, out=w.get("s0" + tag, (n, m), np.float32))
                c0 = np.compress(more, c0, axis=1, out=w.get("c0" + tag, (n, m), np.float32))
                if r0 is not None:
                    r0 = np.compress(more, r0, axis=1, out=w.get("r0" + tag, (n, m)))
            p += _chebyshev_step(err, cs, ss)
            m = len(active)
            # θ(p) = θ(x) + K·(p − x) [+ R(p) − R(x)]: sin/cos by angle addition from the values at x
            delta = w.get("delta", (n, m), np.float32)
            if self.field is None:
                np.matmul(self._kd32, (p - xa).astype(np.float32), out=delta)
            else:
                rp, weights = self._field_at(p.T, w)
                d64 = np.matmul(self._kd, p - xa, out=w.get("theta", (n, m)))
                d64 += rp
                d64 -= r0
                np.copyto(delta, d64, casting="same_kind")
            sd = np.sin(delta, out=w.get("sd", (n, m), np.float32))
            cd = np.cos(delta, out=delta)
            tmp = w.get("tmp32", (n, m), np.float32)
            s = np.multiply(s0, cd, out=w.get("s", (n, m), np.float32))
            s += np.multiply(c0, sd, out=tmp)
            c = np.multiply(c0, cd, out=w.get("c", (n, m), np.float32))
            c -= np.multiply(s0, sd, out=tmp)


def _sincos(theta: np.ndarray, w: "_Work") -> tuple[np.ndarray, np.ndarray]:
    """sin, cos (float32) of float64 phases (overwritten: reduced to [−π, π] in float64), evaluated in
    float32 (vectorised SIMD, ~20x faster than float64 here; 1.2e-7 rad, i.e. ~1 µm on metre waves —
    far below the 1 cm budget)."""
    turns = np.multiply(theta, 1.0 / TWO_PI, out=w.get("turns", theta.shape))
    np.rint(turns, out=turns)
    turns *= TWO_PI
    theta -= turns
    reduced = w.get("reduced", theta.shape, np.float32)
    np.copyto(reduced, theta, casting="same_kind")
    return (np.sin(reduced, out=w.get("s0a", theta.shape, np.float32)),
            np.cos(reduced, out=w.get("c0a", theta.shape, np.float32)))


def surface_key(ocean: Ocean, weather: Weather) -> str:
    """Everything the wave set depends on (not the level, not sim_time), as JSON (pydantic's own
    serialiser, in C: the fields in their declared order, so the same state gives the same text)."""
    o = ocean.model_dump_json(exclude={"enabled", "level", "lod_error", "detail_resolution"})
    return f"[{o}, {json.dumps(weather.wind_speed)}, {json.dumps(weather.wind_direction)}]"


def sea_surface(ocean: Ocean, weather: Weather, wave_count: int | None = None) -> SeaSurface:
    """The sea of a scene (cached: the field is integrated once per bathymetry + wave set)."""
    return _sea_surface_cached(surface_key(ocean, weather), wave_count or ocean.wave_count)


@lru_cache(maxsize=8)
def _sea_surface_cached(key: str, wave_count: int) -> SeaSurface:
    o, wind_speed, wind_direction = json.loads(key)
    ocean = Ocean.model_validate(o)
    spectrum = sea_spectrum(wind_speed, wind_direction, ocean.sea_state, ocean.fetch_km, ocean.duration_h)
    swell = ocean.swell
    mesh, detail = wave_bands(spectrum, wave_count, DETAIL_WAVES, swell.height, swell.period, swell.direction)
    detail = calibrate_detail(mesh, detail, spectrum.wind)
    bathy = ocean.bathymetry
    h_ref = bathy.depth
    waves = reference_waves(mesh, h_ref)
    kp = float(wavenumber(spectrum.omega_p, h_ref))
    q_ref = float(shore_steepness(ocean.steepness, np.asarray(kp * h_ref)))
    field = wave_field(bathy, waves, ocean.steepness, spectrum.omega_p) if waves.n else None
    return SeaSurface(spectrum, waves, detail, field, q_ref, h_ref, second_order_coefficient(mesh))
