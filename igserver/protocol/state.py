"""The accepted scene state: one owner, all-or-nothing updates, a revision counter streams wait on.

Every update builds a complete new ``Scene`` and validates it before swapping the reference, so a
rejected message leaves the previous object untouched (there is nothing to roll back). Updates run on
the event loop thread only, which makes them atomic with respect to each other without a lock.
"""

from __future__ import annotations

import asyncio
import math
import time
from typing import Any, Callable

from pydantic import ValidationError

from ..scene.model import Effect, Scene
from ..scene.patch import apply_patch, at_sim_time, validate_wire
from .clock import IGClock, sends_sim_time
from .problems import ProblemError, from_validation_error


def stamp_effect_changes(old: Scene, new: Scene, now: float | None = None) -> Scene:
    """Set ``changed_at = now`` (the IG clock's sim_time; default the new state's) on effects that appeared
    or switched ``active``, so the renderer fades.

    ``changed_at`` belongs to the IG: whatever the client sent there is overwritten on a switch.
    """
    previous = {effect.id: effect for effect in old.effects}
    now = new.time.sim_time if now is None else now
    changed = False
    effects: list[Effect] = []
    for effect in new.effects:
        before = previous.get(effect.id)
        if before is None or before.active != effect.active:
            effect = effect.model_copy(update={"changed_at": now})
            changed = True
        elif effect.changed_at != before.changed_at:
            # not a switch: keep the IG's own timestamp so a client cannot restart a fade by echoing state
            effect = effect.model_copy(update={"changed_at": before.changed_at})
            changed = True
        effects.append(effect)
    return new.model_copy(update={"effects": effects}) if changed else new


class StateStore:
    def __init__(self, scene: Scene, on_accept: Callable[[Scene], None] | None = None, clock: IGClock | None = None):
        self.clock = clock or IGClock(scene.time.sim_time)
        self._scene = scene
        self.revision = 0
        self.accepted_at = time.perf_counter()  # when the current revision was accepted (latency metric)
        self._changed = asyncio.Event()
        self._on_accept = on_accept
        self._good: tuple[int, Scene] | None = None  # the last revision that rendered, and its state
        self.rendered_revision = -1  # the newest revision a frame has shown (-1 before the first)
        # DELETEd effects fading out: id -> the sim_time their fade ends, when they leave the state
        self._removing: dict[str, float] = {}

    @property
    def scene(self) -> Scene:
        """The accepted state at the IG clock's sim_time now: what a frame rendered now shows."""
        now = self.clock.sim_time()
        if self._removing:
            self._drop_faded(now)
        return at_sim_time(self._scene, now)

    # -- DELETEd effects: they fade out, then leave; meanwhile their id and their slot may be taken again
    def remove_after_fade(self, effect_id: str) -> None:
        """The effect (already inactive) leaves the state when its fade-out ends."""
        effect = next(e for e in self._scene.effects if e.id == effect_id)
        # changed_at None: inactive since the state began, nothing to fade
        self._removing[effect_id] = -math.inf if effect.changed_at is None else effect.changed_at + effect.fade

    def keep(self, effect_id: str) -> None:
        """A new effect took the id of a DELETEd one: it stays."""
        self._removing.pop(effect_id, None)

    def fading_out(self) -> dict[str, float]:
        """DELETEd effects still fading: id -> the sim_time they leave, soonest first."""
        return dict(sorted(self._removing.items(), key=lambda item: item[1]))

    def _drop_faded(self, now: float) -> None:
        gone = {effect_id for effect_id, end in self._removing.items() if end <= now}
        if not gone:
            return
        for effect_id in gone:
            del self._removing[effect_id]
        # Not a new revision: a faded-out effect draws nothing (fade level 0), so no frame changes.
        effects = [effect for effect in self._scene.effects if effect.id not in gone]
        self._scene = self._scene.model_copy(update={"effects": effects})

    def _accept(self, new: Scene, tree: Any = None) -> Scene:
        host_time = sends_sim_time(tree)
        if host_time is not None:  # a host that sends sim_time drives the clock (host mode)
            self.clock.host_sent(host_time)
        now = self.clock.sim_time()
        new = at_sim_time(stamp_effect_changes(self._scene, new, now), now)
        if self._removing:  # a removal ends when its effect is gone or burning again
            inactive = {effect.id for effect in new.effects if not effect.active}
            self._removing = {i: end for i, end in self._removing.items() if i in inactive}
        self._scene = new
        self.revision += 1
        self.accepted_at = time.perf_counter()
        if self._on_accept is not None:
            self._on_accept(new)
        self._notify()
        return new

    def clock_changed(self) -> Scene:
        """The IG clock was set, paused or handed over: a new revision, so streams show it at once."""
        return self._accept(self._scene)

    def mark_rendered(self, revision: int) -> None:
        """A frame of ``revision`` rendered: it is the state to fall back to if a later one cannot render."""
        self.rendered_revision = max(self.rendered_revision, revision)
        if revision == self.revision:
            self._good = (revision, self._scene)

    def fall_back(self, failed_revision: int) -> int | None:
        """Replace the state of ``failed_revision`` (it hung or crashed the renderer) by the last state that
        rendered, as a new revision; returns that revision, or None when there is nothing to go back to."""
        if self._good is None or failed_revision != self.revision or self._good[0] == failed_revision:
            return None
        self._accept(self._good[1])
        self._good = (self.revision, self._scene)
        return self._good[0]

    def _notify(self) -> None:
        # one Event per revision: waiters hold the event of the revision they saw, set exactly once
        event, self._changed = self._changed, asyncio.Event()
        event.set()

    async def wait_for_change(self, revision: int, timeout: float | None = None) -> bool:
        """Wait until the revision moves past ``revision``; False on timeout."""
        if self.revision != revision:
            return True
        try:
            await asyncio.wait_for(self._changed.wait(), timeout)
        except asyncio.TimeoutError:
            return False
        return True

    def validate_replace(self, tree: Any, prefix: tuple = ()) -> Scene:
        if not isinstance(tree, dict):
            raise ProblemError("validation", "a state message must be a map", [{"pointer": "#", "detail": "expected a map"}])
        try:
            return validate_wire(tree)
        except ValidationError as exc:
            raise from_validation_error(exc, prefix) from None

    def validate_patch(self, tree: Any, prefix: tuple = ()) -> Scene:
        if not isinstance(tree, dict):
            raise ProblemError("validation", "a patch must be a map", [{"pointer": "#", "detail": "expected a map"}])
        try:
            return apply_patch(self._scene, tree, strict=True)
        except ValidationError as exc:
            raise from_validation_error(exc, prefix) from None

    def replace(self, tree: Any) -> Scene:
        return self._accept(self.validate_replace(tree), tree)

    def patch(self, tree: Any) -> Scene:
        return self._accept(self.validate_patch(tree), tree)

    def set_validated(self, scene: Scene, tree: Any = None) -> Scene:
        """Accept a scene from ``validate_patch``/``validate_replace`` (validated against the current state);
        ``tree`` is the message it came from (a ``time.sim_time`` in it hands the clock to the host)."""
        return self._accept(scene, tree)
