"""One exposure for every worker's channels: the front meters the union of their meter cells.

One renderer meters the union of its channels' cells and steps one eye (render/multiview.py), so
adjacent channels show the same luminance as the same grey. Across workers each renderer sees only its
own channels, so the front does it: every worker returns its cells with its frame; the front meters
their union (``display_metered_ev100``), steps its one ``EyeAdaptation`` and sends that (EV100, metered
luminance) with the next frame to every worker, which applies it instead of its own meter. Every
channel of every frame has the same exposure; the meter acts one frame later than in one renderer
(33 ms at 30 fps, against the eye's 0.4-4 s adaptation). Where the eye would show the new state at once
(the first frame, a paused clock, a jump in time, adaptation off) and the exposure moved by more than
``REDRAW_EV``, the frame is drawn again with the new exposure, so a still picture is never one
exposure behind.
"""

from __future__ import annotations

import numpy as np

from ..render.post.exposure import EyeAdaptation, display_metered_ev100
from ..scene.model import Scene

REDRAW_EV = 0.05  # EV: about 3.5 % in luminance, under a just-noticeable step between frames


class SharedExposure:
    def __init__(self) -> None:
        self.eye = EyeAdaptation()
        self.current: tuple[float, float] | None = None  # (EV100, metered luminance cd/m^2) to send

    @staticmethod
    def applies(scene: Scene, parts: list[list[str]]) -> bool:
        """Automatic exposure over channels that more than one worker draws."""
        return scene.camera.exposure_ev is None and bool(scene.channels) and sum(1 for p in parts if p) > 1

    def update(self, scene: Scene, cells: list) -> bool:
        """Meter the union of a frame's cells (linear RGB, cd/m^2; None from a worker without any) and step
        the eye; True when the frame should be drawn again with ``current``."""
        cells = [np.asarray(c, np.float64) for c in cells if c is not None and len(c)]
        if not cells:
            return False
        target, meter = display_metered_ev100(np.concatenate(cells))
        ev = self.eye.update(target, scene.time.sim_time, scene.camera.adaptation)
        used, self.current = self.current, (ev, meter)
        return used is None or (ev == target and abs(ev - used[0]) > REDRAW_EV)
