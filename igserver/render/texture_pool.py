"""Textures kept for reuse: a texture that goes out of use waits here for the next of its kind.

Work modelled at a capped rate (the fire's and smoke's keyframes, a few a second) retires one 3D
texture and needs another of the same size at every keyframe. Handing the retired one back
instead of creating and deleting GL objects keeps the frame free of object creation (a driver
allocation, and on a GPU a stall) whatever the keyframe rate.
"""

from __future__ import annotations

import moderngl


class TexturePool:
    """3D float16 textures by (size, components); at most ``keep`` idle ones of each kind."""

    def __init__(self, ctx: moderngl.Context, keep: int = 4):
        self.ctx = ctx
        self.keep = keep
        self._idle: dict[tuple, list[moderngl.Texture]] = {}
        self.created = 0

    def take(self, size: tuple[int, int, int], components: int, filter: tuple[int, int]) -> moderngl.Texture:
        idle = self._idle.get((tuple(size), components))
        if idle:
            tex = idle.pop()
        else:
            tex = self.ctx.texture3d(size, components, dtype="f2")
            tex.repeat_x = tex.repeat_y = tex.repeat_z = False
            self.created += 1
        tex.filter = filter
        return tex

    def give(self, tex: moderngl.Texture) -> None:
        idle = self._idle.setdefault((tuple(tex.size), tex.components), [])
        if len(idle) < self.keep:
            idle.append(tex)
        else:
            tex.release()

    def release(self) -> None:
        for idle in self._idle.values():
            for tex in idle:
                tex.release()
        self._idle.clear()
