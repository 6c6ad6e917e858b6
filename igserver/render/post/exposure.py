"""Automatic exposure that behaves like an adapting eye.

Meter: the mean luminance M (cd/m^2) of what the camera sees, estimated on the CPU each frame from
the sky-view table (sky directions of a 16 x 9 grid over the frustum), the ground/sea (a 0.15
reflectance under the horizontal illuminance) and local lights near the camera. The mean, not
the log-mean: a bright sunset sky must pull the exposure down (as a camera's average meter or
the eye's pupil do) rather than blow out.

Steady state: a uniform field of luminance M would be shown at the key k(M), KEY_DAY by day,
falling at night like a Naka-Rushton response (the eye never fully compensates darkness: night
must read as night, Ferwerda et al. 1996; Pattanaik et al. 2000):
    k(M) = KEY_DAY sqrt(M / (M + SIGMA)).
The exposure is then chosen in DISPLAY space (display_metered_ev100): the mean displayed value of
the view's samples equals D(k(M)), D the tone curve + sRGB, so the displayed brightness follows M
and never rises while the light falls, whatever the sky's shape does (a sunset).
In EV100 (ISO 12232 / the reflected-light calibration K = 12.5 used by frame.glsl's
u_exposure = 1 / (1.2 * 2^EV100)): EV100 = log2(1 / (1.2 exposure)).

Temporal adaptation (state kept by the renderer between frames, driven by sim_time deltas of at most MAX_STREAM_DT; a frame at the same sim_time as the last, or
after a jump, starts adapted, so re-rendering a state is deterministic):
    EV <- EV_target + (EV - EV_target) exp(-dt / tau),
tau = DAY_REFERENCE = 3000.0  # cd/m^2, a bright day view: the key is KEY_DAY there
DAY_SLOPE = 0.06  # key ~ M^0.06: 10x less light, 13 % lower key
TAU_LIGHT = 0.4 s when the scene gets brighter (pupil and cone bleaching: fractions of a
second to a second), TAU_DARK = 4 s when it gets darker (the fast cone phase of dark adaptation;
full rod adaptation takes tens of minutes, which a simulator cannot wait for). A fixed
camera.exposure_ev always wins; camera.adaptation = false gives the steady state every frame.
"""

from __future__ import annotations

import math

import numpy as np

from ...photometry import LUMA

KEY_DAY = 0.12  # display-linear value of the mean luminance by day (before the tone curve)
SIGMA = 0.05  # cd/m^2: below this the picture darkens (mesopic range 0.005..5 cd/m^2)
DAY_REFERENCE = 3000.0  # cd/m^2, a bright day view: the key is KEY_DAY there
DAY_SLOPE = 0.06  # key ~ M^0.06: 10x less light, 13 % lower key
TAU_LIGHT = 0.4  # s, adapting to more light
TAU_DARK = 4.0  # s, adapting to less light
GROUND_REFLECTANCE = 0.15
EV_MIN, EV_MAX = -16.0, 24.0
MAX_OVER_MEAN_EV = 2.5  # the display meter may expose at most this much more than the average meter
SOLVE_TOLERANCE_EV = 1e-4  # 1/60 of one 8-bit level at mid-grey (~0.006 EV)
TYPICAL_SLOPE = 0.17  # per EV: the slope of the mean displayed value in log2(exposure) at a typical root
MAX_STREAM_DT = 1.0  # s: frames further apart in sim_time are not one continuous view


def key_of(m: float) -> float:
    """Display-linear key of a uniform field of luminance m (cd/m^2): Naka-Rushton at night, and
    by day a slight rise with the light (Stevens: an adapted eye still sees brighter light as
    brighter), so the displayed brightness falls strictly as the sun sets."""
    m = max(m, 1e-9)
    return KEY_DAY * math.sqrt(m / (m + SIGMA)) * (max(m, 1.0) / DAY_REFERENCE) ** DAY_SLOPE


def aces_fit(x):
    """The tone curve of post/tonemap.glsl (Narkowicz 2015), numpy mirror."""
    x = np.asarray(x, dtype=np.float64)
    # minimum(maximum()) is np.clip without its wrapper's cost (the meter calls this ~20 times a frame)
    return np.minimum(np.maximum((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 0.0), 1.0)


def linear_to_srgb(c):
    c = np.asarray(c, dtype=np.float64)
    return np.where(c <= 0.0031308, c * 12.92, 1.055 * np.power(np.maximum(c, 0.0031308), 1 / 2.4) - 0.055)


WHITE_THRESHOLD = 1.0  # display-linear input of the brightest channel where the path to white starts
WHITE_STOPS = 10.0  # stops above WHITE_THRESHOLD where a colour is white


def display_transform(rgb, hue_weight=0.0):
    """Display-linear colour (..., 3) of exposed linear sRGB (..., 3): the ACES fit per channel with
    the highlights' path to white, numpy mirror of post/tonemap.glsl display_transform (its comment
    gives the reasoning). With m the brightest channel's input and t the curve per channel:
        s = clamp(log2(m / WHITE_THRESHOLD) / WHITE_STOPS, 0, 1),  w = s^2 (3 - 2 s),
        out = t + w (max(t) - t).
    Below the threshold w = 0 and the colour is the plain curve's. ``hue_weight`` (..., 1) or scalar:
    a low sun's disk as the sky pass marks it, tone-mapped on its largest channel with its hue kept
    and by that weight no path to white (the meter cannot see the mark: it passes 0)."""
    x = np.asarray(rgb, dtype=np.float64)
    t = aces_fit(x)
    m = np.max(x, axis=-1, keepdims=True)
    hue_weight = np.asarray(hue_weight, dtype=np.float64)
    if np.any(hue_weight > 0.0):
        t = t + hue_weight * (aces_fit(m) * x / np.maximum(m, 1e-12) - t)
    return _to_white(t, _stops_over(m), hue_weight)


def _stops_over(m):
    """log2(m / WHITE_THRESHOLD): the brightest channel's input m above the threshold, in stops."""
    return np.log2(np.maximum(m, 1e-30) / WHITE_THRESHOLD)


def _to_white(t, stops, hue_weight=0.0):
    """The fit's colours t (..., 3) moved toward white by their brightest channel's ``stops`` over
    the threshold (..., 1), less the ``hue_weight`` of a low sun's disk."""
    s = np.minimum(np.maximum(stops / WHITE_STOPS, 0.0), 1.0)
    w = s * s * (3.0 - 2.0 * s) * (1.0 - hue_weight)
    return t + w * (np.max(t, axis=-1, keepdims=True) - t)


# Up to this many cells past the path to white are moved one by one in Python floats (the same
# IEEE operations in the same order as _to_white, so the same values): cheaper than numpy's calls.
FEW_HOT_CELLS = 8


def _to_white_cell(t: list, stops: float) -> tuple:
    """_to_white of one colour ``t`` (3 floats) whose brightest channel is ``stops`` over the
    threshold (no hue weight)."""
    s = min(max(stops / WHITE_STOPS, 0.0), 1.0)
    w = s * s * (3.0 - 2.0 * s)  # (_to_white's factor 1 - hue_weight is 1 here: exact)
    top = max(t)
    return tuple(c + w * (top - c) for c in t)


def displayed(x):
    """Displayed value (0..1) of a display-linear GREY value (any shape), as the post pass shows it:
    the path to white leaves grey unchanged. Colours (..., 3): displayed_rgb."""
    return linear_to_srgb(aces_fit(x))


def displayed_rgb(rgb, hue_weight=0.0):
    """Displayed colour (0..1, (..., 3)) of exposed linear sRGB, as the post pass shows it (before
    its dither)."""
    return linear_to_srgb(display_transform(rgb, hue_weight))


def display_metered_ev100(samples: np.ndarray) -> tuple[float, float]:
    """EV100 that makes the mean DISPLAYED value of the view's samples (cd/m^2: luminances (N,), or
    linear RGB (N, 3), shown as the post pass does: displayed_rgb, the curve per channel with the
    path to white) equal the display of a uniform field at the samples' mean luminance M under the
    steady key k(M): the meter works in display space, so a sunset sky that grows relatively
    brighter than the rest pulls the exposure down instead of brightening the picture, and the
    displayed mean follows D(k(M)), monotone in M.
    Returns (EV100, M). False position on log2(exposure) (the mean is monotone in it)."""
    samples = np.maximum(np.asarray(samples, dtype=np.float64), 0.0)
    lum = samples @ LUMA if samples.ndim == 2 else samples
    # Colours (N, 3) are shown with the path to white; their stops over its threshold at e = 0 once
    # (at exposure 2^e they are e more), and only the cells past it are moved: of the cells that can
    # pass it at the highest exposure tried (hot_cells), those past it at e.
    stops = (_stops_over(np.maximum(np.maximum(samples[:, :1], samples[:, 1:2]), samples[:, 2:3]))
             if samples.ndim == 2 else None)
    hottest = float(np.max(stops)) if stops is not None and stops.size else -math.inf
    m = max(float(np.mean(lum)), 1e-9)
    key = key_of(m)
    target = float(displayed(key))
    e0 = math.log2(key / m)
    lo_limit, hi_limit = e0 - 12.0, e0 + MAX_OVER_MEAN_EV
    hot_cells = np.flatnonzero(stops[:, 0] + hi_limit > 0.0) if hottest + hi_limit > 0.0 else None
    hot_stops = None if hot_cells is None else stops[hot_cells, 0]

    n = samples.size

    def excess(e: float) -> float:
        # aces_fit and linear_to_srgb inlined (the same operations in the same order; samples >= 0,
        # so the fit's lower clip changes nothing), the solve's inner loop.
        x = samples * 2.0 ** e
        shown = 2.51 * x
        shown += 0.03
        shown *= x
        den = 2.43 * x
        den += 0.59
        den *= x
        den += 0.14
        shown /= den
        np.minimum(shown, 1.0, out=shown)
        if hottest + e > 0.0:
            hot = hot_cells[hot_stops + e > 0.0]
            if len(hot) <= FEW_HOT_CELLS:
                for i in hot.tolist():
                    shown[i] = _to_white_cell(shown[i].tolist(), float(stops[i, 0]) + e)
            else:
                shown[hot] = _to_white(shown[hot], stops[hot] + e)
        low = shown <= 0.0031308
        srgb = np.maximum(shown, 0.0031308, out=x)
        np.power(srgb, 1 / 2.4, out=srgb)
        srgb *= 1.055
        srgb -= 0.055
        np.multiply(shown, 12.92, out=srgb, where=low)
        return float(np.add.reduce(srgb, axis=None) / n) - target

    # The mean displayed value is monotone in e = log2(exposure) (each channel is along k x). The
    # root lies within 12 EV below the average meter's e0 = log2(key / M), and the result at most
    # MAX_OVER_MEAN_EV above it (below: the limit): the root is bracketed from e0 toward it (a first
    # step of the distance a slope of TYPICAL_SLOPE would give, then the secant's estimate through
    # the last two points, each overshot by a quarter, at least 0.02 EV, at most 8x the last step,
    # clamped to the limits), then found by false position (Illinois) to SOLVE_TOLERANCE_EV: ~4
    # evaluations (the meter runs on the CPU twice a frame).
    f0 = excess(e0)
    root = None
    if f0 == 0.0:
        root = e0
    else:
        direction = 1.0 if f0 < 0.0 else -1.0  # toward the root
        near, f_near = e0, f0
        step = max(1.25 * abs(f0) / TYPICAL_SLOPE, 0.02)
        while True:
            far = min(max(near + direction * step, lo_limit), hi_limit)
            f_far = excess(far)
            if (f_far >= 0.0) if direction > 0 else (f_far <= 0.0):
                break
            if far in (lo_limit, hi_limit):
                root = far  # the root lies beyond the limit: the limit
                break
            slope = (f_far - f_near) / (far - near)
            guess = abs(f_far / slope) if slope * direction > 0.0 else math.inf
            step = min(max(1.25 * guess, 0.02), 8.0 * abs(far - near))
            near, f_near = far, f_far
        if root is None:
            if direction > 0:
                lo, f_lo, hi, f_hi = near, f_near, far, f_far
            else:
                lo, f_lo, hi, f_hi = far, f_far, near, f_near
            if f_lo >= 0.0:
                root = lo
            elif f_hi <= 0.0:
                root = hi
    if root is None:
        side = 0
        root = 0.5 * (lo + hi)
        for _ in range(60):
            previous, root = root, (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
            f = excess(root)
            if f < 0.0:
                lo, f_lo = root, f
                if side == -1:
                    f_hi *= 0.5
                side = -1
            else:
                hi, f_hi = root, f
                if side == 1:
                    f_lo *= 0.5
                side = 1
            if hi - lo < SOLVE_TOLERANCE_EV or abs(root - previous) < 0.1 * SOLVE_TOLERANCE_EV or f == 0.0:
                break
            # the next secant step would move the root by less than that: it is found
            if abs(f) * (hi - lo) < 0.1 * SOLVE_TOLERANCE_EV * (f_hi - f_lo):
                break
    # Never more than MAX_OVER_MEAN_EV above the plain average meter (exposure = key / M): a view
    # that is mostly black with a few bright things (space with the sun, a lamp at night) would
    # otherwise be lifted until its black reads grey.
    cap = key / m * 2.0 ** MAX_OVER_MEAN_EV
    exposure = cap if root >= hi_limit else min(2.0 ** root, cap)
    return float(np.clip(math.log2(1.0 / (1.2 * exposure)), EV_MIN, EV_MAX)), m


def exposure_of_ev100(ev100: float) -> float:
    return 1.0 / (1.2 * 2.0 ** ev100)


def frustum_directions(view, nx: int = 16, ny: int = 9) -> np.ndarray:
    """Unit camera-relative world directions through a grid of pixel centres (the camera's basis
    and frustum tangents, as frame.glsl's view_ray; no projection matrix, so no depth convention)."""
    left, right, bottom, top = view.tangents
    tx = left + (right - left) * (np.arange(nx) + 0.5) / nx
    ty = bottom + (top - bottom) * (np.arange(ny) + 0.5) / ny
    X, Y = np.meshgrid(tx, ty)
    rot = np.asarray(view.rotation, dtype=np.float64)  # columns right, forward, up
    d = rot[:, 1][None] + X.reshape(-1, 1) * rot[:, 0][None] + Y.reshape(-1, 1) * rot[:, 2][None]
    return d / np.linalg.norm(d, axis=1, keepdims=True)


class EyeAdaptation:
    """Adaptation state of one renderer: the EV100 applied last frame and the sim_time it was at."""

    def __init__(self):
        self.ev100: float | None = None
        self.sim_time: float | None = None

    def update(self, target_ev100: float, sim_time: float, enabled: bool = True) -> float:
        if not enabled or self.ev100 is None or self.sim_time is None:
            self.ev100 = target_ev100
        else:
            dt = sim_time - self.sim_time
            if not (0.0 < dt <= MAX_STREAM_DT):
                # Same instant (a re-render, a paused clock, an unrelated state) or not a continuous
                # stream (time jumped back or by more than a second): show the adapted state.
                self.ev100 = target_ev100
            else:
                tau = TAU_LIGHT if target_ev100 > self.ev100 else TAU_DARK
                self.ev100 = target_ev100 + (self.ev100 - target_ev100) * math.exp(-dt / tau)
        self.sim_time = sim_time
        return self.ev100
