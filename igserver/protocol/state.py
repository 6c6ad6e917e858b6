"""The accepted scene state: one owner, all-or-nothing updates, a revision counter streams wait on.

Every update builds a complete new ``Scene`` and validates it before swapping the reference, so a
rejected message leaves the previous object untouched (there is nothing to roll back). Updates run on
the event loop thread only, which makes them atomic with respect to each other without a lock.
"""

from __future__ import annotations

import asyncio
import time
from typing import Any, Callable

from pydantic import ValidationError

from ..scene.model import Effect, Scene
from ..scene.patch import apply_patch, validate_wire
from .problems import ProblemError, from_validation_error


def stamp_effect_changes(old: Scene, new: Scene) -> Scene:
    """Set ``changed_at = sim_time`` on effects that appeared or switched ``active``, so the renderer fades.

    ``changed_at`` belongs to the IG: whatever the client sent there is overwritten on a switch.
    """
    previous = {effect.id: effect for effect in old.effects}
    now = new.time.sim_time
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
    def __init__(self, scene: Scene, on_accept: Callable[[Scene], None] | None = None):
        self._scene = scene
        self.revision = 0
        self.accepted_at = time.perf_counter()  # when the current revision was accepted (latency metric)
        self._changed = asyncio.Event()
        self._on_accept = on_accept

    @property
    def scene(self) -> Scene:
        return self._scene

    def _accept(self, new: Scene) -> Scene:
        new = stamp_effect_changes(self._scene, new)
        self._scene = new
        self.revision += 1
        self.accepted_at = time.perf_counter()
        if self._on_accept is not None:
            self._on_accept(new)
        self._notify()
        return new

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
        return self._accept(self.validate_replace(tree))

    def patch(self, tree: Any) -> Scene:
        return self._accept(self.validate_patch(tree))

    def set_validated(self, scene: Scene) -> Scene:
        """Accept a scene from ``validate_patch``/``validate_replace`` (validated against the current state)."""
        return self._accept(scene)
