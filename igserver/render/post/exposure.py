"""Automatic exposure that behaves like an adapting eye.

Meter: the mean luminance M (cd/m^2) of what the camera sees, estimated on the CPU each frame from
the sky-view table (sky directions of a 16 x 9 grid over the frustum), the ground/sea (a 0.15
reflectance under the horizontal illuminance) and local lights near the camera. The mean, not
the log-mean: a bright sunset sky must pull the exposure down (as a camera's average meter or
the eye's pupil do) rather than blow out.

Steady state: the displayed value of the mean is a key k(M) that stays at KEY_DAY by day and falls
at night like a Naka-Rushton response (the eye never fully compensates darkness: night must read
as night, Ferwerda et al. 1996; Pattanaik et al. 2000):
    k(M) = KEY_DAY sqrt(M / (M + SIGMA)),    exposure = k(M) / M,
so the displayed mean k(M) is monotone in M: the picture never brightens while the light falls.
In EV100 (ISO 12232 / the reflected-light calibration K = 12.5 used by frame.glsl's
u_exposure = 1 / (1.2 * 2^EV100)): EV100 = log2(1 / (1.2 exposure)).

Temporal adaptation (state kept by the renderer between frames, driven by sim_time deltas of at most MAX_STREAM_DT; a frame at the same sim_time as the last, or
after a jump, starts adapted, so re-rendering a state is deterministic):
    EV <- EV_target + (EV - EV_target) exp(-dt / tau),
tau = TAU_LIGHT = 0.4 s when the scene gets brighter (pupil and cone bleaching: fractions of a
second to a second), TAU_DARK = 4 s when it gets darker (the fast cone phase of dark adaptation;
full rod adaptation takes tens of minutes, which a simulator cannot wait for). A fixed
camera.exposure_ev always wins; camera.adaptation = false gives the steady state every frame.
"""

from __future__ import annotations

import math

import numpy as np

KEY_DAY = 0.12  # display-linear value of the mean luminance by day (before the tone curve)
SIGMA = 0.1  # cd/m^2: below this the picture darkens (mesopic range 0.005..5 cd/m^2)
TAU_LIGHT = 0.4  # s, adapting to more light
TAU_DARK = 4.0  # s, adapting to less light
GROUND_REFLECTANCE = 0.15
EV_MIN, EV_MAX = -16.0, 24.0
MAX_STREAM_DT = 1.0  # s: frames further apart in sim_time are not one continuous view


def steady_ev100(mean_luminance: float) -> float:
    m = max(mean_luminance, 1e-9)
    key = KEY_DAY * math.sqrt(m / (m + SIGMA))
    exposure = key / m
    return float(np.clip(math.log2(1.0 / (1.2 * exposure)), EV_MIN, EV_MAX))


def exposure_of_ev100(ev100: float) -> float:
    return 1.0 / (1.2 * 2.0 ** ev100)


def frustum_directions(view, nx: int = 16, ny: int = 9) -> np.ndarray:
    """Unit camera-relative world directions through a grid of pixel centres."""
    inv = np.linalg.inv(view.view_proj)
    xs = (np.arange(nx) + 0.5) / nx * 2 - 1
    ys = (np.arange(ny) + 0.5) / ny * 2 - 1
    X, Y = np.meshgrid(xs, ys)
    ndc_far = np.stack([X, Y, np.ones_like(X), np.ones_like(X)], -1).reshape(-1, 4)
    ndc_near = ndc_far.copy()
    ndc_near[:, 2] = -1.0
    far = ndc_far @ inv.T
    near = ndc_near @ inv.T
    d = far[:, :3] / far[:, 3:4] - near[:, :3] / near[:, 3:4]
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
