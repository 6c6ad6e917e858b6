"""GLSL as package data: ``#include "path"`` resolution, feature ``#define``s, a program cache.

Paths are relative to ``igserver/render`` (e.g. ``common/brdf.glsl``, ``sky/gradient.glsl``).
Shader variants are compiled with only the features in use: the defines are part of the cache key.
"""

from __future__ import annotations

import os
import re
from functools import lru_cache
from importlib import resources

import moderngl
import numpy as np

GLSL_VERSION = "#version 450 core"
_INCLUDE = re.compile(r'^\s*#include\s+"([^"]+)"\s*$', re.MULTILINE)


@lru_cache(maxsize=None)
def read_glsl(path: str) -> str:
    return resources.files("igserver.render").joinpath(path).read_text()


def expand(path: str, seen: frozenset[str] = frozenset()) -> str:
    """Source of ``path`` with includes expanded once each (include guards are implicit)."""
    if path in seen:
        return ""
    seen = seen | {path}

    def repl(match: re.Match) -> str:
        return expand(match.group(1), seen)

    return _INCLUDE.sub(repl, read_glsl(path))


def assemble(path: str, stage: str, defines: dict[str, object] | None = None) -> str:
    lines = [GLSL_VERSION, f"#define {stage}_SHADER 1"]
    if os.environ.get("IGSERVER_ATMOSPHERE_DIRECT") == "1":
        # Study knob: every pass walks the 4D atmosphere tables per pixel instead of reading the
        # per-frame sky-view table (the pre-wave-2 cost, for before/after timings and image error).
        lines.append("#define ATMOSPHERE_DIRECT_TABLES 1")
    for key, value in sorted((defines or {}).items()):
        lines.append(f"#define {key} {value}" if value is not True else f"#define {key} 1")
    lines.append("#line 1")
    return "\n".join(lines) + "\n" + expand(path)


class ProgramCache:
    """One compiled program per (files, defines); pipelines stay resident in the render process.

    ``context_defines`` go into every program of this context (e.g. its depth clip range).
    """

    def __init__(self, ctx: moderngl.Context, context_defines: dict | None = None):
        self.ctx = ctx
        self.context_defines = dict(context_defines or {})
        self._programs: dict[tuple, moderngl.Program | moderngl.ComputeShader] = {}

    def program(self, vertex: str, fragment: str, defines: dict | None = None) -> moderngl.Program:
        defines = {**self.context_defines, **(defines or {})}
        key = ("prog", vertex, fragment, tuple(sorted((defines or {}).items())))
        if key not in self._programs:
            self._programs[key] = self.ctx.program(
                vertex_shader=assemble(vertex, "VERTEX", defines),
                fragment_shader=assemble(fragment, "FRAGMENT", defines),
            )
        return self._programs[key]

    def compute(self, path: str, defines: dict | None = None) -> moderngl.ComputeShader:
        defines = {**self.context_defines, **(defines or {})}
        key = ("comp", path, tuple(sorted((defines or {}).items())))
        if key not in self._programs:
            self._programs[key] = self.ctx.compute_shader(assemble(path, "COMPUTE", defines))
        return self._programs[key]

    def __len__(self) -> int:
        return len(self._programs)


def uniform_inputs(program, values: dict, skip: tuple = ()) -> tuple:
    """The values ``values`` gives ``program``'s active uniforms (all but ``skip``), as an exact,
    hashable key: what a table the program draws or fills was made from, so the table can be kept
    until one of them changes (a uniform the shader gains joins the key by itself)."""
    return tuple((name, _frozen(values[name])) for name in sorted(program)
                 if name in values and name not in skip and isinstance(program[name], moderngl.Uniform))


def _frozen(value):
    """A uniform's value as a hashable, exactly comparable key part."""
    if isinstance(value, np.ndarray):
        return (value.dtype.str, value.shape, value.tobytes())
    if isinstance(value, (list, tuple)):
        return tuple(_frozen(v) for v in value)
    return value


def set_uniforms(program, values: dict[str, object]) -> None:
    """Set the uniforms a program actually has; the rest are silently not needed by it."""
    for name, value in values.items():
        # A dict lookup: moderngl programs define no __contains__, so ``name in program`` walked
        # every member for every name (~15 ms of Python per demo frame over all passes).
        member = program.get(name, None)
        if member is not None:
            if isinstance(value, bytes):
                member.write(value)
            elif isinstance(member, moderngl.Uniform):
                member.value = value
            elif hasattr(member, "value"):  # a block's binding (hasattr on a Uniform would read it from GL)
                member.value = value
