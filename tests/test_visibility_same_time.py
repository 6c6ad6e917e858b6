"""A visibility change at an unchanged sim_time, on its own (no state left by another test).

igserver/render/sky/haze.py HazeTransition: log beta eases over ``atmosphere.visibility_transition``
seconds of sim_time, and "a frame at the same sim_time as the last (a paused clock, a re-render) shows the
new state at once, so renders stay deterministic" (docs/atmosphere.md says the same); 0 s = at once. So a
host that changes only the visibility while sim_time stands still gets the new fog in that very frame,
and the frame a transition later shows the same full fog (no ease restarted from the clear air).

Every reference frame is the steady state of its scene: drawn by the same renderer with its between-frame
state (eased fog, eye adaptation) fresh, i.e. with no history, then the renderer's own state is put back."""

from __future__ import annotations

import numpy as np
import pytest

from igserver.render.frame import FrameState
from igserver.scene.model import Scene

T = 4321.0  # s of sim_time, far from the times other tests use (not that it matters: see _settle)
CLEAR_M, FOG_M = 30_000.0, 300.0


def scene(visibility: float, sim_time: float, transition: float) -> Scene:
    # a 2-m eye looking 5 deg up at a noon-ish sun: the lower rows the ground out to the horizon, the upper
    # rows the sky (a 300-m fog hides the ground beyond a few hundred metres and whitens the sky)
    return Scene.model_validate({
        "camera": {"width": 64, "height": 36, "heading": 180.0, "pitch": 5.0, "position": [0.0, 0.0, 2.0],
                   "adaptation": False},
        "time": {"utc": "2024-06-21T12:00:00Z", "sun_override": {"elevation": 30.0, "azimuth": 180.0},
                 "sim_time": sim_time},
        "atmosphere": {"visibility": visibility, "visibility_transition": transition}})


def steady(renderer, s: Scene) -> np.ndarray:
    """The frame of ``s`` with no history (what the fog layer says for its visibility)."""
    kept = renderer.frame_state
    renderer.frame_state = FrameState()
    try:
        return renderer.render(s).rgba[..., :3].astype(np.int16)
    finally:
        renderer.frame_state = kept


def frame(renderer, s: Scene) -> np.ndarray:
    return renderer.render(s).rgba[..., :3].astype(np.int16)


def _settle(renderer, visibility: float, transition: float) -> None:
    """Whatever an earlier test left in the renderer, the clear air settled at T: a frame 100 s before T
    (a gap longer than any transition: taken at once, or an ease begun), then one at T (the same gap)."""
    renderer.render(scene(visibility, T - 100.0, transition))
    renderer.render(scene(visibility, T, transition))
    assert renderer.frame_state.haze.settled


def max_diff(a: np.ndarray, b: np.ndarray) -> int:
    return int(np.abs(a - b).max())


@pytest.mark.parametrize("transition", [2.0, 0.0])
def test_visibility_change_at_an_unchanged_sim_time_shows_at_once(renderer, transition):
    clear_ref = steady(renderer, scene(CLEAR_M, T, transition))
    fog_ref = steady(renderer, scene(FOG_M, T, transition))
    later = T + max(transition, 2.0)  # 2 s: the eye takes the frame's own exposure (see below)
    fog_later_ref = steady(renderer, scene(FOG_M, later, transition))
    # the two visibilities make clearly different frames (else the checks below would prove nothing):
    # the fog's veil moves the ground and the sky by tens of levels
    assert max_diff(clear_ref, fog_ref) > 40 and abs(float(clear_ref.mean() - fog_ref.mean())) > 10.0

    _settle(renderer, CLEAR_M, transition)
    clear = frame(renderer, scene(CLEAR_M, T, transition))
    # a re-render at the same sim_time is the same frame (determinism)
    assert max_diff(clear, clear_ref) <= 1
    # only the visibility changes, sim_time stands: the full fog in this frame (not the clear air held,
    # not a step of the ease); one level: the same GL draws, bit-for-bit up to the driver's rounding
    fog = frame(renderer, scene(FOG_M, T, transition))
    assert max_diff(fog, fog_ref) <= 1, (max_diff(fog, fog_ref), max_diff(fog, clear_ref))
    assert renderer.frame_state.haze.settled
    # and a transition later (time moving again) still the full fog: the change is not eased in afresh
    # from the clear air behind it
    assert max_diff(frame(renderer, scene(FOG_M, later, transition)), fog_later_ref) <= 1


def test_visibility_change_while_time_moves_eases_over_the_transition(renderer):
    """The counterpart (the same scenes): with sim_time moving, the change eases in over the transition from
    the frame that brings it (that frame still shows the clear air: no pop), half way it is neither, and a
    transition after it the fog is complete. Frames 2 s apart: the eye's exposure, which blends frames under
    1 s apart, takes each frame's own target, as in the references."""
    transition = 4.0
    t1, t2, t3 = T + 2.0, T + 4.0, T + 6.0
    clear_ref = steady(renderer, scene(CLEAR_M, t1, transition))
    fog_first_ref = steady(renderer, scene(FOG_M, t1, transition))
    mid_clear_ref = steady(renderer, scene(CLEAR_M, t2, transition))
    mid_fog_ref = steady(renderer, scene(FOG_M, t2, transition))
    fog_ref = steady(renderer, scene(FOG_M, t3, transition))

    _settle(renderer, CLEAR_M, transition)
    first = frame(renderer, scene(FOG_M, t1, transition))
    # the ease starts from the clear air's extinction (the layer's new droplet phase function and albedo
    # already apply, a few tens of levels near the sun): far nearer the clear frame than the fog's
    assert max_diff(first, clear_ref) < 0.5 * max_diff(clear_ref, fog_first_ref), (
        max_diff(first, clear_ref), max_diff(clear_ref, fog_first_ref))
    mid = frame(renderer, scene(FOG_M, t2, transition))
    assert not renderer.frame_state.haze.settled
    assert max_diff(mid, mid_clear_ref) > 10 and max_diff(mid, mid_fog_ref) > 10
    lo, hi = sorted((float(mid_clear_ref.mean()), float(mid_fog_ref.mean())))
    assert lo < float(mid.mean()) < hi, (lo, float(mid.mean()), hi)
    end = frame(renderer, scene(FOG_M, t3, transition))
    assert renderer.frame_state.haze.settled
    assert max_diff(end, fog_ref) <= 1


def test_settled_haze_is_not_eased_again(monkeypatch):
    """A stream whose visibility does not change: once the transition has settled, each frame returns
    the settled value without easing again (counted); a new value eases from it as before."""
    import numpy as np

    from igserver.render.sky.haze import HazeTransition

    steps = []
    original = HazeTransition._step
    monkeypatch.setattr(HazeTransition, "_step", lambda self, *a: steps.append(a) or original(self, *a))
    haze = HazeTransition()
    first = haze.apply(np.array([1e-4, 2e-4, 3e-4]), 10.0, 0.0)
    for i in range(1, 6):
        assert np.array_equal(haze.apply(np.array([1e-4, 2e-4, 3e-4]), 10.0, i / 30), first)
    assert len(steps) == 1
    start = haze.apply(np.array([1e-3, 2e-3, 3e-3]), 10.0, 6 / 30)  # a new target: the ease starts here
    assert len(steps) == 2 and np.allclose(start, first)
    moving = haze.apply(np.array([1e-3, 2e-3, 3e-3]), 10.0, 7 / 30)
    assert len(steps) == 3 and np.all(moving > first) and np.all(moving < [1e-3, 2e-3, 3e-3])  # easing
