"""The IG clock: the ``sim_time`` every frame is rendered at (docs/design.md#service).

Two modes:
  ``free``  sim_time runs by itself: ``sim_time = base + rate * (now - started)`` on a monotonic clock,
            so fades, flicker, waves and the streams animate with no host connected. Pausable
            (``rate`` kept, time frozen), rate-settable (0.5 = half speed, 0 = frozen), settable.
  ``host``  a host that sends ``time.sim_time`` takes over: from then on the frame shows exactly
            the sim_time the host sent last (simulators that step frame by frame). ``PATCH
            /v1/clock {"mode": "free"}`` hands the clock back; it then runs on from the host's value.

The clock is the one source of ``sim_time``: effect activation stamps ``changed_at`` with ``now()``.
"""

from __future__ import annotations

import time
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

MAX_SIM_TIME = 1e12  # s, the scene model's bound on time.sim_time
MAX_RATE = 1000.0  # sim seconds per real second


class ClockState(BaseModel):
    """What ``GET /v1/clock`` answers."""

    mode: Literal["free", "host"] = Field(..., description="free: runs by itself; host: the host's sim_time")
    sim_time: float = Field(..., description="s, the sim_time a frame rendered now would show")
    rate: float = Field(..., description="sim seconds per real second in free mode")
    paused: bool = Field(..., description="free mode frozen at sim_time")


class ClockChange(BaseModel):
    """``PATCH /v1/clock`` body: any subset; a rejected body changes nothing."""

    # strict, as every message at the protocol edge: false is not a sim_time, "2" is not a rate
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, strict=True)

    mode: Literal["free", "host"] | None = Field(
        None, description="free: run by itself; host: hold until the host sends sim_time")
    rate: float | None = Field(None, ge=0.0, le=MAX_RATE, description="sim seconds per real second")
    paused: bool | None = Field(None, description="freeze (true) or resume (false) free-running time")
    sim_time: float | None = Field(None, ge=0.0, le=MAX_SIM_TIME, description="s, set the clock to this sim_time")


class IGClock:
    """Monotonic, float64. ``now`` is injectable for tests (a fake ``time.monotonic``)."""

    def __init__(self, sim_time: float = 0.0, now=time.monotonic):
        self._now = now
        self.mode: str = "free"
        self.rate = 1.0
        self.paused = False
        self._base = float(sim_time)  # sim_time at _t0
        self._t0 = self._now()

    def _rebase(self) -> None:
        """Fold the elapsed time into the base, so rate/pause changes apply from this instant on."""
        self._base = self.sim_time()
        self._t0 = self._now()

    def sim_time(self) -> float:
        if self.mode == "host" or self.paused:
            return self._base
        return min(self._base + self.rate * (self._now() - self._t0), MAX_SIM_TIME)

    @property
    def running(self) -> bool:
        """True when frames change with real time (the stream must keep rendering)."""
        return self.mode == "free" and not self.paused and self.rate > 0.0

    def host_sent(self, sim_time: float) -> None:
        """A host message carried ``time.sim_time``: the host drives the clock from now on."""
        self.mode = "host"
        self._base = float(sim_time)
        self._t0 = self._now()

    def change(self, change: ClockChange) -> None:
        self._rebase()
        if change.sim_time is not None:
            self._base = change.sim_time
        if change.rate is not None:
            self.rate = change.rate
        if change.paused is not None:
            self.paused = change.paused
        if change.mode is not None:
            self.mode = change.mode

    def state(self) -> ClockState:
        return ClockState(mode=self.mode, sim_time=self.sim_time(), rate=self.rate, paused=self.paused)


def sends_sim_time(tree) -> float | None:
    """The ``time.sim_time`` a (validated) state message carries, or None when it carries none."""
    if isinstance(tree, dict) and isinstance(tree.get("time"), dict) and "sim_time" in tree["time"]:
        value = tree["time"]["sim_time"]
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            return float(value)
    return None
