"""Small helpers shared by the tests (importable as ``helpers``: pytest puts tests/ on sys.path)."""

from __future__ import annotations

import os
import signal
import time

import numpy as np

from igserver.photometry import LUMA
from igserver.scene import Scene, apply_patch


def tiny(patch: dict | None = None, width: int = 64, height: int = 36) -> Scene:
    base = Scene.model_validate({"camera": {"width": width, "height": height}})
    return apply_patch(base, patch or {})


def luminance(rgba: np.ndarray) -> np.ndarray:
    return rgba[..., :3].astype(np.float64) @ LUMA


def kill_render_process(service) -> int:
    """SIGKILL a RenderService's render process, as a crash would, and wait until the service sees
    it gone (its next render restarts it: a stream may have done so already). Returns the killed pid."""
    pid = service.pid
    assert pid, "the render process is not running"
    os.kill(pid, signal.SIGKILL)
    deadline = time.monotonic() + 5.0
    while service.alive and service.pid == pid and time.monotonic() < deadline:  # is_alive() reaps it
        time.sleep(0.01)
    return pid


class GLWork:
    """Counts the GL work a block submits, at moderngl's boundary (independent of igserver's own pass
    bookkeeping): draws, compute dispatches, framebuffer blits, clears and framebuffer binds.

    ``with GLWork() as work: renderer.render(scene)`` then ``work.counts`` ({kind: n}) and ``work.calls``
    (the sequence of (kind, detail)). A pass that runs costs GL commands even when it draws nothing
    (it binds its target), so equal counts mean no pass ran that the other frame did not run.
    """

    HOOKS = {
        "draw": ("VertexArray", "render"),
        "dispatch": ("ComputeShader", "run"),
        "blit": ("Context", "copy_framebuffer"),
        "clear": ("Framebuffer", "clear"),
        "bind_fbo": ("Framebuffer", "use"),
    }

    def __init__(self):
        self.calls: list[tuple[str, str]] = []
        self._saved: list[tuple[type, str, object]] = []

    @property
    def counts(self) -> dict[str, int]:
        out = {kind: 0 for kind in self.HOOKS}
        for kind, _ in self.calls:
            out[kind] += 1
        return out

    def __enter__(self) -> "GLWork":
        import moderngl

        for kind, (cls_name, method) in self.HOOKS.items():
            cls = getattr(moderngl, cls_name)
            original = getattr(cls, method)
            self._saved.append((cls, method, original))

            def counted(obj, *args, _kind=kind, _original=original, **kwargs):
                self.calls.append((_kind, type(obj).__name__))
                return _original(obj, *args, **kwargs)

            setattr(cls, method, counted)
        return self

    def __exit__(self, *exc) -> None:
        for cls, method, original in reversed(self._saved):
            setattr(cls, method, original)
        self._saved.clear()


def synthesized_levels(renderer, tiles: list[np.ndarray], resolution: int, t: float = 0.0,
                       omegas: list[np.ndarray] | None = None) -> list[list[np.ndarray]]:
    """Each tile's detail-map levels (render/water/detail_synth.py) as the GL makes them, read back:
    per tile of waves (m, n, A k, phase at t = 0) and its ω (rad/s; None: 0, a still tile), the levels
    at time ``t`` (float32 (S, S, 4) each, rows along the tile's y). Textures made for the call."""
    from igserver.render.water.detail_synth import DetailSynthGL, SynthTables

    ctx = renderer.ctx
    omegas = omegas or [np.zeros(len(w)) for w in tiles]
    tables = SynthTables([(w[:, 0:3], o, w[:, 3]) for w, o in zip(tiles, omegas)], resolution)
    textures = [ctx.texture((resolution, resolution), 4, dtype="f4") for _ in tiles]
    synth = DetailSynthGL(ctx, renderer.programs)
    try:
        for tex in textures:
            tex.build_mipmaps()
        synth.write(textures, tables, t, len(tiles))
        chain = int(np.log2(resolution)) + 1
        return [[np.frombuffer(tex.read(level=level), np.float32).reshape(resolution >> level, resolution >> level, 4)
                 for level in range(chain)] for tex in textures]
    finally:
        synth.release()
        for tex in textures:
            tex.release()


def with_and_without_skip(renderer, scene, switch: str) -> tuple[np.ndarray, np.ndarray, dict]:
    """The water pass's picture of ``scene`` with the block variant ``switch`` (a WaterPass attribute:
    skip_minified_maps, skip_faded_streaks, skip_offshore_land) on and off, and its stats with it on:
    (fast, full, stats)."""
    water = renderer.graph.passes["water"]
    fast = renderer.render(scene).rgba
    stats = dict(water.stats)
    setattr(water, switch, False)
    try:
        full = renderer.render(scene).rgba
    finally:
        setattr(water, switch, True)
    return fast, full, stats


def forcing_defines(monkeypatch, **forced) -> None:
    """Every program and compute shader compiled with ``forced`` defines over the pass's own."""
    from igserver.render import shaders

    program, compute = shaders.ProgramCache.program, shaders.ProgramCache.compute
    monkeypatch.setattr(shaders.ProgramCache, "program",
                        lambda self, vertex, fragment, defines=None: program(self, vertex, fragment, {**(defines or {}), **forced}))
    monkeypatch.setattr(shaders.ProgramCache, "compute",
                        lambda self, path, defines=None: compute(self, path, {**(defines or {}), **forced}))
