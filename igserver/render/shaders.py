"""GLSL as package data: ``#include "path"`` resolution, feature ``#define``s, a program cache.

Paths are relative to ``igserver/render`` (e.g. ``common/brdf.glsl``, ``sky/sky.glsl``).
Shader variants are compiled with only the features in use: the defines are part of the cache key.
"""

from __future__ import annotations

import re
from functools import lru_cache
from importlib import resources

import moderngl
import numpy as np

from . import bindings

GLSL_VERSION = "#version 450 core"
_INCLUDE = re.compile(r'^\s*#include\s+"([^"]+)"\s*$', re.MULTILINE)


@lru_cache(maxsize=None)
def read_glsl(path: str) -> str:
    if path in GENERATED:
        return GENERATED[path]()
    return resources.files("igserver.render").joinpath(path).read_text()


def _frame_block_glsl() -> str:
    from .frame_block import glsl
    return glsl()


# GLSL made from Python tables (one declaration for both sides), included like package files.
GENERATED = {"generated/frame_block.glsl": _frame_block_glsl, "generated/bindings.glsl": bindings.glsl}


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
    for key, value in sorted((defines or {}).items()):
        lines.append(f"#define {key} {value}" if value is not True else f"#define {key} 1")
    lines.append("#line 1")
    return "\n".join(lines) + "\n" + expand(path)


class ProgramCache:
    """One compiled program per (files, defines); pipelines stay resident in the render process.

    ``context_defines`` go into every program of this context (e.g. its depth clip range). Draw programs read the frame's
    uniform block (``FRAME_BLOCK`` 1, render/frame_block.py); compute programs fill tables with
    their own camera or sun and take those values as plain uniforms unless they ask for the block.
    """

    def __init__(self, ctx: moderngl.Context, context_defines: dict | None = None):
        self.ctx = ctx
        self.context_defines = dict(context_defines or {})
        self._programs: dict[tuple, moderngl.Program | moderngl.ComputeShader] = {}
        self._quick: dict[tuple, tuple] = {}  # the key of the program of exact arguments

    def program(self, vertex: str, fragment: str, defines: dict | None = None) -> moderngl.Program:
        # The program of these exact arguments (a pass asks every frame): the key below is a
        # function of them, so the look-up skips building it.
        quick = ("prog", vertex, fragment, tuple(defines.items()) if defines else ())
        held = self._programs.get(self._quick.get(quick))
        if held is not None:
            return held
        defines = {**self.context_defines, "FRAME_BLOCK": 1, **(defines or {})}
        key = ("prog", vertex, fragment, tuple(sorted((defines or {}).items())))
        if key not in self._programs:
            sources = (assemble(vertex, "VERTEX", defines), assemble(fragment, "FRAGMENT", defines))
            program = self.ctx.program(vertex_shader=sources[0], fragment_shader=sources[1])
            self._programs[key] = _note_block_reads(program, defines, sources)
        self._quick[quick] = key
        return self._programs[key]

    def compute(self, path: str, defines: dict | None = None) -> moderngl.ComputeShader:
        quick = ("comp", path, tuple(defines.items()) if defines else ())
        held = self._programs.get(self._quick.get(quick))
        if held is not None:
            return held
        defines = {**self.context_defines, "FRAME_BLOCK": 0, **(defines or {})}
        key = ("comp", path, tuple(sorted((defines or {}).items())))
        if key not in self._programs:
            source = assemble(path, "COMPUTE", defines)
            self._programs[key] = _note_block_reads(self.ctx.compute_shader(source), defines, (source,))
        self._quick[quick] = key
        return self._programs[key]

    def __len__(self) -> int:
        return len(self._programs)

    def __iter__(self):
        """The programs compiled so far (draw and compute)."""
        return iter(list(self._programs.values()))


def _note_block_reads(program, defines: dict, sources: tuple[str, ...]):
    """Keep on ``program`` what ``block_reads`` needs to tell which frame-block fields it reads."""
    program._igserver_sources = sources if defines.get("FRAME_BLOCK") else None
    program._igserver_block_reads = None if defines.get("FRAME_BLOCK") else frozenset()
    return program


def block_reads(program) -> frozenset:
    """The frame-block fields ``program`` really reads. Every member of a std140 block counts as
    active, so GL cannot say; the same sources compiled with plain uniforms can: the compiler keeps
    exactly the uniforms the code uses. Done once per program, and only for programs whose inputs
    are asked for (``uniform_inputs``)."""
    reads = getattr(program, "_igserver_block_reads", frozenset())
    if reads is not None:
        return reads
    from .frame_block import NAMES
    plain = tuple(src.replace("#define FRAME_BLOCK 1\n", "#define FRAME_BLOCK 0\n", 1) for src in program._igserver_sources)
    ctx = program.ctx
    probe = (ctx.program(vertex_shader=plain[0], fragment_shader=plain[1]) if len(plain) == 2
             else ctx.compute_shader(plain[0]))
    reads = frozenset(name for name in probe if name in NAMES)
    probe.release()
    program._igserver_block_reads = reads
    return reads


def uniform_inputs(program, values: dict, skip: tuple = ()) -> tuple:
    """The values ``values`` gives ``program``'s active uniforms (all but ``skip``), as an exact,
    hashable key: what a table the program draws or fills was made from, so the table can be kept
    until one of them changes (a uniform the shader gains joins the key by itself)."""
    return tuple((name, _frozen(values[name])) for name in _input_names(program) if name in values and name not in skip)


def _input_names(program) -> tuple:
    """The names uniform_inputs reads, sorted: the frame-block fields the program reads and its
    uniforms (found once per program: they are fixed when it is linked)."""
    try:
        return program._igserver_input_names
    except AttributeError:
        names = set(block_reads(program))
        names.update(name for name in program if isinstance(program[name], moderngl.Uniform))
        program._igserver_input_names = tuple(sorted(names))
        return program._igserver_input_names


def _frozen(value):
    """A uniform's value as a hashable, exactly comparable key part."""
    kind = type(value)
    if kind is float or kind is int or kind is bytes:
        return value
    if kind is tuple:  # a tuple of numbers (most vectors) is its own key
        try:
            hash(value)
            return value
        except TypeError:  # it holds a list or an array
            return tuple(_frozen(v) for v in value)
    if isinstance(value, np.ndarray):
        return (value.dtype.str, value.shape, value.tobytes())
    if isinstance(value, (list, tuple)):
        return tuple(_frozen(v) for v in value)
    return value


def set_uniforms(program, values: dict[str, object]) -> None:
    """Set the uniforms a program actually has; the rest are silently not needed by it.

    A uniform's value is program state in GL: it stays until written again. Each program keeps the
    last value written to each of its uniforms (``_written``) and a value equal to it is not written
    again, so what does not change between frames (texture units, the sea's tables, materials, the
    sun while the clock runs) costs a dict look-up and a comparison instead of a driver call. Every
    write to a program's uniforms goes through here, or the memory would be stale.
    """
    written = _written(program)
    members = _settable(program)
    # Walk the shorter of the two: a program reads a few dozen of the frame's hundred values.
    names = members.keys() & values.keys() if len(values) > len(members) else values
    for name in names:
        member = members.get(name)
        if member is None:
            continue
        value = values[name]
        key = (value.dtype.str, value.shape, value.tobytes()) if isinstance(value, np.ndarray) else value
        try:
            if written.get(name, _UNSET) == key:
                continue
        except ValueError:  # a sequence holding arrays: compare nothing, write it
            pass
        value = _fitted(member, value)
        if isinstance(value, bytes):
            member.write(value)
        else:
            member.value = value
        written[name] = key


def _fitted(member, value):
    """The part of an array value that the program's uniform holds. A driver drops the trailing elements
    of a uniform array that the shader never reads (Mesa and NVIDIA both do, each by its own analysis),
    so ``uniform vec4 a[8]`` may be 2 elements long in one driver and 8 in another. The caller writes
    what the shader may read: the tail the program lacks is cut here, and bytes short of the program's
    length are padded with zeros (elements the shader does not read, kept by a driver that could not
    prove so)."""
    n = member.array_length
    if isinstance(value, bytes):
        size = n * member.element_size
        return value[:size] if len(value) >= size else value + bytes(size - len(value))
    if (isinstance(value, (list, tuple)) and len(value) > n
            and (n > 1 or member.dimension == 1 or isinstance(value[0], (list, tuple)))):
        return value[0] if n == 1 else tuple(value[:n])
    return value


def _settable(program) -> dict:
    """``program``'s members a value can be written to: its uniforms and its uniform blocks'
    bindings (looked up once per program; moderngl's ``program[name]`` is a dict look-up per call)."""
    try:
        return program._igserver_settable
    except AttributeError:
        members = {}
        for name in program:
            member = program[name]
            if isinstance(member, (moderngl.Uniform, moderngl.UniformBlock)):
                members[name] = member
        program._igserver_settable = members
        return members


_UNSET = object()


def _written(program) -> dict:
    """The values last written to ``program``'s uniforms (kept on the program object: it lives and
    dies with the GL program)."""
    try:
        return program._igserver_written
    except AttributeError:
        program._igserver_written = {}
        return program._igserver_written
