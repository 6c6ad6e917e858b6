"""GLSL as package data: ``#include "path"`` resolution, feature ``#define``s, a program cache.

Paths are relative to ``igserver/render`` (e.g. ``common/brdf.glsl``, ``sky/sky.glsl``).
Shader variants are compiled with only the features in use: the defines are part of the cache key.
"""

from __future__ import annotations

import operator
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
    until one of them changes (a uniform the shader gains joins the key by itself).

    The names ``values`` holds are those it held last time when it holds none of the others (one
    set test); their values are gathered in C and are their own key when all are hashable
    (numbers, tuples of numbers, bytes), else frozen one by one."""
    skip = tuple(skip)
    held = _present(program).get(skip)
    if held is None or not values.keys().isdisjoint(held[2]):
        held = None
    else:
        try:
            current = held[1](values)
        except KeyError:  # one of them is gone
            held = None
    if held is None:
        names = tuple(name for name in _input_names(program) if name in values and name not in skip)
        absent = frozenset(_input_names(program)) - set(names) - set(skip)
        getter = operator.itemgetter(*names) if len(names) > 1 else (lambda v: tuple(v[n] for n in names))
        held = _present(program)[skip] = (names, getter, absent)
        current = getter(values)
    try:
        hash(current)
        return tuple(zip(held[0], current))
    except TypeError:  # an array or a list among them
        return tuple((name, _frozen(value)) for name, value in zip(held[0], current))


def _present(program) -> dict:
    """Per ``skip``: the names uniform_inputs last found in its values, their getter, the rest."""
    try:
        return program._igserver_present
    except AttributeError:
        program._igserver_present = {}
        return program._igserver_present


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

    A large dict (the frame's values) is first compared whole: the program keeps, per set of its
    uniforms that such a dict gave it, those values as one tuple (``_Given``), held while no other
    value is written to one of them. The same set and the same values (compared in C): every one of
    those uniforms already holds its value, and nothing is compared name by name; else only the
    values that differ from that tuple go through the name-by-name write.
    """
    members = _settable(program)
    if len(values) < WHOLE_MIN_VALUES:
        _write(program, members, values.keys() & members.keys() if len(values) > len(members) else values, values)
        return
    givens = _givens(program)
    for given in givens:
        if not values.keys().isdisjoint(given.others):
            continue
        try:
            current = given.getter(values)
        except KeyError:
            continue
        # the names this dict gives the program are exactly given.order
        changed = given.order
        if given.held and set(map(type, current)).isdisjoint(_MUTABLE):
            try:
                if current == given.values:
                    return
                # the uniforms hold given.values: only those whose value differs may need a write
                changed = [name for name, a, b in zip(given.order, current, given.values) if a != b]
            except ValueError:  # a sequence holding arrays: compare name by name
                pass
        _write(program, members, changed, values)
        given.values, given.held = current, True
        return
    names = tuple(sorted(members.keys() & values.keys()))
    _write(program, members, names, values)
    if len(givens) >= MAX_GIVENS:
        givens.pop(0)
    givens.append(_Given(names, frozenset(members.keys()) - set(names), values))


# Values whose content may change while the object stays the same: compared name by name (by bytes).
_MUTABLE = frozenset((np.ndarray, list))
# Dicts of at least this many values are compared whole first (set_uniforms); a program keeps the
# last MAX_GIVENS sets of its uniforms that such dicts gave it.
WHOLE_MIN_VALUES = 16
MAX_GIVENS = 4


class _Given:
    """A set of ``names`` a large dict gave a program (and the program's other uniforms, which it did
    not hold) and the values it gave them; ``held``: no other value written to one of them since."""

    __slots__ = ("order", "names", "others", "getter", "values", "held")

    def __init__(self, names: tuple, others: frozenset, values: dict):
        self.order, self.names, self.others, self.held = names, frozenset(names), others, True
        getter = operator.itemgetter(*names) if names else (lambda values: ())
        self.getter = getter if len(names) != 1 else (lambda values: (getter(values),))
        self.values = self.getter(values)


def _givens(program) -> list:
    try:
        return program._igserver_givens
    except AttributeError:
        program._igserver_givens = []
        return program._igserver_givens


def _write(program, members: dict, names, values: dict) -> None:
    """Write those of ``names`` (all in ``values``) whose value differs from the one last written."""
    written = _written(program)
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
        for given in getattr(program, "_igserver_givens", ()):
            if name in given.names:
                given.held = False


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
