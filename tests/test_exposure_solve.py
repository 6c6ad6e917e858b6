"""The exposure meter's solve (post/exposure.py display_metered_ev100) lands on the root of its
equation, mean displayed value of the samples = D(k(M)), to its tolerance, in few evaluations:
against a bisection of the same equation to float64 precision, for views from a bright day to a
dark night with a fire, grey luminances and colours with the path to white in play."""

import math

import numpy as np
import pytest

from igserver.photometry import LUMA
from igserver.render.post import exposure
from igserver.render.post.exposure import (EV_MAX, EV_MIN, MAX_OVER_MEAN_EV, SOLVE_TOLERANCE_EV, display_metered_ev100,
                                           displayed, displayed_rgb, key_of)


def _reference_ev100(samples: np.ndarray) -> float:
    samples = np.maximum(np.asarray(samples, np.float64), 0.0)
    lum = samples @ LUMA if samples.ndim == 2 else samples
    m = max(float(np.mean(lum)), 1e-9)
    key = key_of(m)
    target = float(displayed(key))
    shown = displayed_rgb if samples.ndim == 2 else displayed

    def excess(e):
        return float(np.mean(shown(samples * 2.0 ** e))) - target

    e0 = math.log2(key / m)
    lo, hi = e0 - 12.0, e0 + 12.0
    if excess(lo) >= 0.0:
        root = lo
    elif excess(hi) <= 0.0:
        root = hi
    else:
        for _ in range(200):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if excess(mid) < 0.0 else (lo, mid)
        root = 0.5 * (lo + hi)
    exposure_ = min(2.0 ** root, key / m * 2.0 ** MAX_OVER_MEAN_EV)
    return float(np.clip(math.log2(1.0 / (1.2 * exposure_)), EV_MIN, EV_MAX))


def _views():
    rng = np.random.default_rng(3)
    day = rng.lognormal(0.0, 1.0, (576, 3)) * 3000.0
    sunset = day * np.array([1.0, 0.6, 0.3]) * 0.01
    sunset[:20] *= 300.0  # the sun's glow past the path to white
    night = rng.lognormal(0.0, 0.5, (576, 3)) * 1e-3
    night[:4] = np.array([1.0, 0.3, 0.05]) * 50.0  # a fire: the average meter's limit decides
    grey = rng.lognormal(0.0, 2.0, 144) * 10.0
    sea = np.concatenate([np.full(80, 0.4), rng.uniform(50.0, 400.0, 64)])  # sky over a dark sea
    black = np.zeros(144)
    return {"day": day, "sunset": sunset, "night_fire": night, "grey": grey, "sea": sea, "black": black}


@pytest.mark.parametrize("name", list(_views()))
def test_the_solve_lands_on_the_root_in_few_evaluations(name, monkeypatch):
    samples = _views()[name]
    calls = []
    power = np.power

    class Counting:  # counts the displayed-value evaluations (one power per evaluation)
        def __getattr__(self, attr):
            return getattr(np, attr)

        @staticmethod
        def power(*args, **kwargs):
            calls.append(1)
            return power(*args, **kwargs)

    monkeypatch.setattr(exposure, "np", Counting())
    ev, m = display_metered_ev100(samples)
    monkeypatch.undo()
    assert ev == pytest.approx(_reference_ev100(samples), abs=SOLVE_TOLERANCE_EV)
    assert m == pytest.approx(max(float(np.mean(samples @ LUMA if samples.ndim == 2 else samples)), 1e-9))
    # the displayed target (one power) and the evaluations: the earlier full bracket took 10 to 12
    assert len(calls) <= 8, len(calls)
