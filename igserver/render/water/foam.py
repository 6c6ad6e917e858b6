"""The foam the water shader draws: coverage from the surface's Jacobian against a threshold chosen so
the drawn whitecap fraction follows the measured one, dithered into wind streaks by a tabulated noise."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...scene.model import Scene
from ...water.surface import SeaSurface, whitecap_coverage
from ..bindings import FRAME_UNITS
from ..camera import CameraView

# The foam foam.glsl draws: a probability rising from 0 at J = threshold + FOAM_EDGE[0] to 1 at
# threshold − FOAM_EDGE[1] (smoothstep), now and FOAM_LAG seconds ago (the same water particle) with
# the older foam's opacity fading as exp(−lag / FOAM_DECAY_S); the strongest of the three is the
# opacity, dithered into streaks by noise through a ramp of width FOAM_SOFT (its mean over the noise:
# foam_mean).
FOAM_EDGE = (0.02, 0.06)
FOAM_SOFT = 0.5
FOAM_LAG = (1.5, 4.0)  # s
FOAM_DECAY_S = 3.5  # s: e-folding time of a whitecap's brightness (Monahan 1971: 3.53 s)
FOAM_OLD_BRIGHTNESS = 0.5  # old foam's opacity (foam.glsl FOAM_OLD): its contrast over the sea relative to fresh foam's
SURF_FOAM_JACOBIAN = 0.97  # J threshold where the waves break on a bathymetry (surf zone): every compressed crest


def foam_mean(f: np.ndarray) -> np.ndarray:
    """The drawn foam's mean over the dither noise (u uniform on [0, 1]) at opacity f:
    E[clamp((f − (1 − w) u) / w, 0, 1)], w = FOAM_SOFT, in closed form (foam.glsl foam_mean)."""
    w = FOAM_SOFT
    covered = np.where(f < w, f * f / (2.0 * w), np.where(
        f <= 1.0 - w, f - 0.5 * w, (f - w) + (w * w - (f - 1.0 + w) ** 2) / (2.0 * w)))
    return covered / (1.0 - w)


def foam_decay() -> tuple[float, float]:
    """Opacity of the foam FOAM_LAG seconds old."""
    return tuple(math.exp(-lag / FOAM_DECAY_S) for lag in FOAM_LAG)


def foam_coverage(threshold: float, j_now: np.ndarray, j_past: tuple[np.ndarray, np.ndarray],
                  streaks: float = 0.0) -> np.ndarray:
    """The foam's mean cover per point, weighted by its brightness (foam.glsl foam_vertex, then the
    dither's mean and the fresh/old colour): what a photograph of the sea counts as whitecap."""
    m, fresh = foam_cover_and_freshness(threshold, j_now, j_past, streaks)
    return m * (FOAM_OLD_BRIGHTNESS + (1.0 - FOAM_OLD_BRIGHTNESS) * fresh)


def foam_cover_and_freshness(threshold: float, j_now: np.ndarray, j_past: tuple[np.ndarray, np.ndarray],
                             streaks: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Per point the resolved foam's mean cover and the share of it that is fresh (foam.glsl
    foam_vertex where no wave is faded)."""
    edge = FOAM_EDGE[0] + FOAM_EDGE[1]

    def probability(j):
        x = np.clip((threshold + FOAM_EDGE[0] - j) / edge, 0.0, 1.0)
        return x * x * (3.0 - 2.0 * x)

    now = foam_mean(probability(j_now))
    d1, d2 = foam_decay()
    m = np.maximum(now, foam_mean(np.maximum(d1 * probability(j_past[0]),
                                             np.maximum(d2 * probability(j_past[1]), streaks))))
    return m, np.where(m > 1e-6, now / np.maximum(m, 1e-6), 1.0)


def streak_size(wind: float) -> tuple[float, float]:
    """m along and across the wind: a cell of the finest streak noise. Wind-row foam streaks lengthen
    with the wind (Beaufort 7-9: "foam blown in streaks along the wind", denser and longer as it
    rises): 0.625 m per m/s along (14 m at Beaufort 9), 2.5 to 19 m; FOAM_STREAK_WIDTH across. The
    wind rows (FOAM_OCTAVE_SCALE) are 8 and 16 times longer: cells 4 times longer than these drew each
    thin streak as one unbroken band, which seen downwind from a bridge converged like speed lines."""
    return 0.625 * min(max(wind, 4.0), 30.0), FOAM_STREAK_WIDTH


def streak_opacity(wind: float) -> float:
    """Opacity of the old foam lying in wind rows over the whole sea (dithered into streaks): none
    below Beaufort 7 (13.9 m/s, "foam begins to be blown in streaks"), 0.25 from Beaufort 11 (28.5
    m/s, "sea completely covered with long white patches of foam lying along the wind"). Counted in
    the whitecap calibration (Monahan's W): the whitecaps make up the rest."""
    x = min(max((wind - 13.9) / (28.5 - 13.9), 0.0), 1.0)
    return 0.25 * x * x * (3.0 - 2.0 * x)


def streak_octave_weights(wind: float) -> tuple[float, float, float]:
    """Per octave of the streak noise (FOAM_OCTAVE_SCALE) its weight in the dither's noise, the
    squares summing to 1: the thin streaks alone up to Beaufort 6 (10.8 m/s), bunched into wind rows
    6 and 24 m wide from Beaufort 8 (17.2 m/s, "well-marked streaks"), the rows as strong as the
    streaks in them (0.75, 0.5, 0.433). An octave of weight 0 is not read."""
    x = min(max((wind - 10.8) / (17.2 - 10.8), 0.0), 1.0)
    x = x * x * (3.0 - 2.0 * x)
    rows = (0.5 * x, 0.433 * x)
    return (math.sqrt(1.0 - rows[0] ** 2 - rows[1] ** 2), *rows)


def streak_variant(streaks: bool, values: dict) -> int:
    """The water program's WATER_FOAM_STREAKS for a block: 0 without the streak noise (faded there),
    1 with the thin streaks and the patches, 2 with the wind rows too (their weight in this frame's
    ``values``, foam_frame's u_foam_octaves, is not 0): the rows' lookups cost the water pass 10 % on
    llvmpipe even where they are not read, so a calm sea's program leaves them out."""
    return 0 if not streaks else 2 if values.get("u_foam_octaves", (1.0, 0.0, 0.0))[1] > 0.0 else 1


# m/s: Beaufort 3, "large wavelets, crests begin to break" (WMO); calmer, the crests are glassy and do
# not break, though Monahan's fit still gives W = 2e-4 at 3.4 m/s and 4e-6 at 1 m/s. Below it the
# water program leaves the foam out (foam_drawn).
FOAM_LEAST_WIND = 3.4


def foam_drawn(sea: SeaSurface, wind: float, threshold_set: bool = False) -> bool:
    """The water program's WATER_FOAM: whether the sea draws foam. Not a sea too calm for whitecaps
    (wind under FOAM_LEAST_WIND) with no surf (no bathymetry field, where the waves break on the
    shallows whatever the wind) and no foam threshold set by hand (``threshold_set``: the tests' and
    the quality report's fixed thresholds)."""
    return threshold_set or sea.field is not None or wind >= FOAM_LEAST_WIND


def dots_defines(values: dict) -> dict:
    """The water program's WATER_FOAM_DOTS and the dots' constants: the far whitecaps drawn as sparse
    dots (foam_streaks.glsl foam_dots) in a sea without wind rows (``values``: the frame's uniforms,
    foam_frame's u_foam_octaves), whose whitecaps are sparse; a storm's foam is dense, its dots would
    be its mean, and its program leaves them out."""
    if values.get("u_foam_octaves", (1.0, 0.0, 0.0))[1] > 0.0:
        return {"WATER_FOAM_DOTS": 0}
    return {"WATER_FOAM_DOTS": 1, "FOAM_DOT_AREA": FOAM_DOT_AREA, "FOAM_DOT_LIFE": FOAM_DOT_LIFE,
            "FOAM_DOT_PERIOD": FOAM_DOT_PERIOD}


def spray_strength(wind: float) -> float:
    """0..1: spindrift blown off the crests, from Beaufort 8 (17.2 m/s: "edges of crests begin to
    break into spindrift") to full at Beaufort 11 (28.5 m/s: "edges of crests blown into froth")."""
    x = min(max((wind - 17.2) / (28.5 - 17.2), 0.0), 1.0)
    return x * x * (3.0 - 2.0 * x)


FOAM_STREAK_WIDTH = 1.5  # m across the wind: a cell of the old foam's finest streak noise (its length: streak_size)
# Per octave of the streak noise (foam_streaks.glsl FOAM_OCTAVE_SCALE_1, _2): its cell's length and width
# over the finest's. Wind rows: thin streaks bunched into bands 6 and 24 m wide (Langmuir rows are
# spaced 2 to 50 m apart, Thorpe 2004), which stay visible where the thin ones are below a pixel.
FOAM_OCTAVE_SCALE = ((1.0, 1.0), (8.0, 4.0), (16.0, 16.0))
# Per lookup of the noise's first channel, the finest octave's and the coarser octaves' (foam_rows), a
# shift in cells, so that the two read unrelated parts of it.
FOAM_OCTAVE_SHIFT = ((0.0, 0.0), (17.37, 29.71))
# The storm streaks' meander (foam_streaks.glsl): a noise of cells this many times the finest's (16x
# longer, 64x wider: 96 m across), anchored to the sea like the octaves.
FOAM_MEANDER_SCALE = (16.0, 64.0)


def rows_channel_cells() -> tuple[tuple[float, float], tuple[float, float]]:
    """The cells (along, across the wind) of the tabulated noise's second and third channels, in cells
    of its first: the coarsest streak octave's and the meander's over the first coarse octave's. The
    wind rows' three noises are then one lookup at that octave's coordinates (foam_streaks.glsl
    foam_rows: llvmpipe pays for every lookup in the shader on every pixel). Whole divisors of
    FOAM_PERIOD, so each channel tiles with the table."""
    base = FOAM_OCTAVE_SCALE[1]
    cells = tuple(tuple(a / b for a, b in zip(scale, base)) for scale in (FOAM_OCTAVE_SCALE[2], FOAM_MEANDER_SCALE))
    assert all(FOAM_PERIOD % c == 0.0 for pair in cells for c in pair), cells
    return cells


# m along and across the wind: a cell of the fresh foam's noise (whitecaps drawn out downwind)
FOAM_PATCH_SIZE = (10.0, 3.0)
FOAM_PATCH_HS = 6.0  # m: the sea's Hs at which a whitecap's patch is FOAM_PATCH_SIZE
# The far whitecaps' dots (foam_streaks.glsl foam_dots): a whitecap's area over its patch cell (a
# quarter: 5 m x 1.5 m in a sea of Hs 6 m, as the patches' noise draws them near; a dot's cover, this
# over the cell's patch cells plus m, stays under 1), the seconds between two breakings of a dot's cell
# (its foam fades over them, FOAM_DECAY_S being 3.5 s), the patch cells the cells' coordinates wrap on
# (a power of two: no repetition within 160 km along the wind at Hs 6 m).
FOAM_DOT_AREA = 0.25
FOAM_DOT_LIFE = 10.0
FOAM_DOT_PERIOD = 16384


def whitecap_patch_size(hs: float) -> tuple[float, float]:
    """m along and across the wind: a cell of the fresh foam's noise for a sea of significant height
    ``hs``. A whitecap spans a part of its breaking crest, so its size goes with the waves' (whitecap
    areas scale with the breaking waves' size, Mironov & Dulov 2008): FOAM_PATCH_SIZE at FOAM_PATCH_HS,
    in proportion below, at least a fifth of it (the surf of a 1 m swell broke into blobs 10 m long)."""
    return tuple(x * min(max(hs / FOAM_PATCH_HS, 0.2), 1.0) for x in FOAM_PATCH_SIZE)
# The noise cells' size the foam's pattern fades by (detail.foam_streaks_needed): each lookup fades by
# its own least side, the last to fade is the coarsest streak octave's.
FOAM_FADE_CELL = max(FOAM_STREAK_WIDTH * FOAM_OCTAVE_SCALE[-1][1], min(FOAM_PATCH_SIZE))
FOAM_STREAK_FADE = 0.75  # cells a pixel spans where the streaks have faded to their mean (foam_streaks.glsl)
FOAM_DRIFT = 0.03  # × wind speed: the surface drift that carries the streaks downwind
FOAM_PERIOD = 64.0  # noise cells per side of the tabulated noise: 0.9 km along the wind, 96 m across (finest octave)
FOAM_NOISE_SIZE = 512  # texels per side: 8 per noise cell (see foam_noise.frag.glsl)
FOAM_NOISE_UNIT = FRAME_UNITS["FOAM_NOISE"]


def wave_lags(sea: SeaSurface, max_waves: int) -> bytes:
    """Per mesh wave (1 − cos ωL₁, sin ωL₁, 1 − cos ωL₂, sin ωL₂) for the lags FOAM_LAG: the phase
    turns gerstner.glsl needs for J at t − L (u_wave_lag). Once per sea state (held with the sea)."""
    return held_per_sea(_LAGS, sea, max_waves, lambda: _wave_lags(sea, max_waves))


_LAGS: dict = {}


def held_per_sea(cache: dict, sea: SeaSurface, extra, compute):
    """``compute()`` kept in ``cache`` per sea state object and ``extra``: the sea is held with its value,
    so its id cannot be reused by another sea meanwhile; at most 16 kept."""
    key = (id(sea), extra)
    held = cache.get(key)
    if held is not None and held[0] is sea:
        return held[1]
    if len(cache) > 16:
        cache.clear()
    value = compute()
    cache[key] = (sea, value)
    return value


def _wave_lags(sea: SeaSurface, max_waves: int) -> bytes:
    table = np.zeros((max_waves, 4), dtype=np.float64)
    n = min(sea.waves.n, max_waves)
    for c, lag in enumerate(FOAM_LAG):
        turn = sea.waves.omega[:n] * lag
        table[:n, 2 * c] = 1.0 - np.cos(turn)
        table[:n, 2 * c + 1] = np.sin(turn)
    return table.astype(np.float32).tobytes()


def foam_frame(scene: Scene, view: CameraView, sea: SeaSurface, wind: float, max_waves: int) -> dict:
    """The foam's per-frame uniforms: the streak noise's frame (foam_streaks.glsl foam_cover) — downwind
    axis and cell sizes, and the camera's noise coordinates per lookup (the finest octave's, the
    rows'), drifted downwind by the time, reduced mod
    the period in float64 so the streaks stay put on the sea at any distance from the origin and any
    sim_time — the lags' decay and the spray's strength."""
    # plain floats: a handful of numbers a frame (numpy's per-call cost is most of their time)
    to = math.radians(scene.weather.wind_direction + 180.0)  # the wind blows from wind_direction
    axis = (math.sin(to), math.cos(to))
    cam_x, cam_y = float(view.position[0]), float(view.position[1])
    size = streak_size(wind)
    t = scene.time.sim_time
    along, side = cam_x * axis[0] + cam_y * axis[1], cam_y * axis[0] - cam_x * axis[1]
    drifted = along - FOAM_DRIFT * wind * t
    offset = np.array([((drifted / (size[0] * sx) + dx) % FOAM_PERIOD, (side / (size[1] * sy) + dy) % FOAM_PERIOD)
                       for (sx, sy), (dx, dy) in zip(FOAM_OCTAVE_SCALE, FOAM_OCTAVE_SHIFT)], dtype=np.float32)
    hs = sea.waves.hs
    patch_size = whitecap_patch_size(hs)
    patch = (drifted / patch_size[0] % FOAM_PERIOD, side / patch_size[1] % FOAM_PERIOD)
    dots = (drifted / patch_size[0] % FOAM_DOT_PERIOD, side / patch_size[1] % FOAM_DOT_PERIOD)
    return {"u_foam_frame": (*axis, 1.0 / size[0], 1.0 / size[1]),
            "u_foam_offset": offset.tobytes(), "u_foam_period": FOAM_PERIOD,
            "u_foam_octaves": streak_octave_weights(wind), "u_foam_patch": (1.0 / patch_size[0], 1.0 / patch_size[1], *patch),
            "u_foam_dots": (*dots, t % (FOAM_DOT_LIFE * 4096.0)),
            "u_foam_noise": FOAM_NOISE_UNIT, "u_foam_decay": (*foam_decay(), SURF_FOAM_JACOBIAN, streak_opacity(wind)),
            "u_spray": (spray_strength(wind), 1.0 / max(hs, 1e-3)),
            "u_wave_lag": wave_lags(sea, max_waves)}


@dataclass(frozen=True)
class FoamCalibration:
    threshold: float  # J threshold of the resolved foam (foam.glsl u_foam_jacobian)
    unresolved_centre: float  # J centre of the unresolved foam's normal tail (u_foam_unresolved.x)
    freshness: float  # share of the drawn foam that is fresh (u_foam_unresolved.y)


_FOAM_CACHE: dict = {}


def drawn_foam_threshold(sea: SeaSurface, wind: float) -> float:
    """The J threshold at which the foam the shader draws covers Monahan's whitecap fraction W of the
    sea on average (``foam_calibration``)."""
    return foam_calibration(sea, wind).threshold


def polya_inverse(p: float) -> float:
    """x with 0.5 + 0.5 sign(x) sqrt(1 − exp(−3.08 x²)) = p (foam.glsl's normal tail, x in units of
    2.2 σ: Pólya's approximation of the normal CDF)."""
    p = min(max(p, 1e-9), 1.0 - 1e-9)
    x = math.sqrt(-math.log(max(1.0 - (2.0 * p - 1.0) ** 2, 1e-300)) / 3.08)
    return x if p >= 0.5 else -x


def foam_calibration(sea: SeaSurface, wind: float) -> FoamCalibration:
    """The foam's thresholds for Monahan's whitecap fraction W of the sea.

    Resolved (the mesh carries every wave): the J threshold at which the drawn foam — its soft
    edge, now and FOAM_LAG earlier, the wind rows, the dither's mean (``foam_coverage``), weighted
    by J, the displaced area each rest point stands for — averages W over the sea's J samples (not
    the J quantile at W, which drew foam over 3 % of the sea at Beaufort 9 instead of 16 %).
    Unresolved (the LOD faded the waves: the foam is the chance that J, normal about the mesh's J
    with the faded waves' variance, is under a centre): the centre where that chance over the sea's
    J (its mean and variance) gives the same brightness-weighted W with the resolved foam's share of
    fresh foam — the chances of the lagged and the fresh foam are not independent (J 1.5 s and 4 s
    apart correlate by +0.4 and −0.7 at Beaufort 9), so they are not combined."""
    return held_per_sea(_FOAM_CACHE, sea, float(wind), lambda: _foam_calibration(sea, wind))


def _foam_calibration(sea: SeaSurface, wind: float) -> FoamCalibration:
    coverage = whitecap_coverage(wind)
    calibration = FoamCalibration(-1.0, -1.0, 1.0)
    if coverage > 0.0 and sea.n > 0:
        j, past = jacobian_history(sea)
        streaks = streak_opacity(wind)
        area = np.maximum(j, 0.0)

        def drawn(t: float) -> float:
            return float(np.average(foam_coverage(t, j, past, streaks), weights=area))

        lo, hi = float(j.min()) - FOAM_EDGE[0], float(j.max()) + FOAM_EDGE[1]  # drawn 0 .. 1
        for _ in range(40):  # bisection: the drawn mean rises with the threshold
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if drawn(mid) < coverage else (lo, mid)
        threshold = 0.5 * (lo + hi)
        m, fresh = foam_cover_and_freshness(threshold, j, past, streaks)
        freshness = float(np.average(m * fresh, weights=area) / max(np.average(m, weights=area), 1e-12))
        mean = float(np.average(j, weights=area))
        var = float(np.average((j - mean) ** 2, weights=area))
        edge2 = 0.25 * (FOAM_EDGE[0] + FOAM_EDGE[1]) ** 2
        want = coverage / (FOAM_OLD_BRIGHTNESS + (1.0 - FOAM_OLD_BRIGHTNESS) * freshness)
        centre = mean + polya_inverse(want) * math.sqrt(edge2 + 4.84 * var)
        calibration = FoamCalibration(threshold, centre, freshness)
    return calibration


def jacobian_history(sea: SeaSurface, points: int = 4000, times=(0.0, 7.3, 19.1),
                     seed: int = 11) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray]]:
    """J of the mesh waves at ``points`` rest points over 1 km² at ``times``, and at the same points
    FOAM_LAG seconds earlier (deterministic)."""
    xy = np.random.default_rng(seed).uniform(-500.0, 500.0, (points, 2))

    def at(shift: float) -> np.ndarray:
        return np.concatenate([sea.evaluate(xy, t - shift, full=False)["jacobian"] for t in times])

    return at(0.0), (at(FOAM_LAG[0]), at(FOAM_LAG[1]))
