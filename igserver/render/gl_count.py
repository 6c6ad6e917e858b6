"""Counting the GL work a block of code submits, at moderngl's boundary.

``with GLCallCounter() as calls: renderer.render(scene)`` wraps, for the duration of the block,
every moderngl entry point that reaches the driver: the methods of moderngl's object classes
(``Texture.use``, ``Buffer.write``, ``VertexArray.render``, ``Context.texture``, ...), the property
setters (``ctx.depth_func = ...``, ``fbo.viewport = ...``), the writes to a program's uniforms
(``Uniform.write``, which its ``value`` setter calls) and to uniform-block bindings.

What is not counted, because it does not reach the driver: a program's member look-ups, property
reads moderngl answers from Python (sizes, ``glo``), ``release`` and ``__del__`` (object lifetime).

Besides the count, the wrappers add up the calling thread's CPU time spent inside the wrapped calls
(``gl_cpu_s``). A frame's host time *outside* GL is then its calling-thread CPU time minus that, less
the wrappers' own overhead (``overhead_s``: calls times the cost of one wrapper, calibrated on a
no-op at entry), which is how ``igserver bench`` reports Python and numpy time per frame.
"""

from __future__ import annotations

import time
from collections import Counter

import moderngl

# moderngl's Python object classes whose methods call into GL.
_CLASSES = ("Context", "Program", "ComputeShader", "Texture", "Texture3D", "TextureArray", "TextureCube",
            "Buffer", "VertexArray", "Framebuffer", "Sampler", "Renderbuffer", "Query", "Scope")
# Methods answered in Python (member look-ups, iteration) or object lifetime: not GL work of a frame.
# (Uniform and UniformBlock are wrapped on their own, below.)
_NOT_GL = {"get", "release", "__getitem__", "__iter__", "__init__", "__del__", "__repr__", "__eq__", "__hash__",
           "__enter__", "__exit__", "__setitem__", "__init_subclass__", "detect_framebuffer"}


class GLCallCounter:
    """GL calls made in a block, by entry point (``by_name``), in total (``total``), and the calling
    thread's CPU seconds spent inside them (``gl_cpu_s``)."""

    def __init__(self):
        self.by_name: Counter = Counter()
        self.gl_cpu_s = 0.0
        self._saved: list[tuple[type, str, object]] = []
        self.wrapper_cost_s = 0.0

    @property
    def total(self) -> int:
        return sum(self.by_name.values())

    @property
    def overhead_s(self) -> float:
        """Estimated CPU seconds the wrappers themselves added to the calling thread."""
        return self.total * self.wrapper_cost_s

    def created(self) -> int:
        """GL objects created in the block (Context factory methods: textures, buffers, programs...)."""
        factories = ("texture", "texture3d", "texture_array", "texture_cube", "depth_texture", "buffer",
                     "framebuffer", "simple_framebuffer", "renderbuffer", "depth_renderbuffer", "program",
                     "compute_shader", "vertex_array", "simple_vertex_array", "sampler", "query", "scope")
        return sum(n for name, n in self.by_name.items() if name in {f"Context.{f}" for f in factories})

    def _timed(self, name: str, fn, *args, **kwargs):
        self.by_name[name] += 1
        t0 = time.thread_time()
        try:
            return fn(*args, **kwargs)
        finally:
            self.gl_cpu_s += time.thread_time() - t0

    def _wrap_method(self, cls: type, attr: str, original) -> None:
        label = f"{cls.__name__}.{attr}"
        counter = self

        def counted(obj, *args, **kwargs):
            return counter._timed(label, original, obj, *args, **kwargs)

        counted.__name__ = attr
        self._saved.append((cls, attr, original))
        setattr(cls, attr, counted)

    def _wrap_function(self, module, name: str) -> None:
        label, original, counter = f"{module.__name__.rsplit('.', 1)[-1]}.{name}", getattr(module, name), self

        def counted(*args, **kwargs):
            return counter._timed(label, original, *args, **kwargs)

        self._saved.append((module, name, original))
        setattr(module, name, counted)

    def _wrap_setter(self, cls: type, attr: str, prop: property) -> None:
        label = f"{cls.__name__}.{attr}="
        counter = self

        def fset(obj, value):
            counter._timed(label, prop.fset, obj, value)

        self._saved.append((cls, attr, prop))
        setattr(cls, attr, property(prop.fget, fset, prop.fdel, prop.__doc__))

    def _wrap_uniform_write(self) -> None:
        """``Uniform.write`` (the ``value`` setter calls it), labelled by the uniform's name."""
        counter, original = self, moderngl.Uniform.write

        def write(obj, data):
            return counter._timed(f"Uniform[{obj.name}].write", original, obj, data)

        self._saved.append((moderngl.Uniform, "write", original))
        moderngl.Uniform.write = write

    def _calibrate(self) -> None:
        """CPU seconds one wrapper adds around a call that does nothing."""
        probe = GLCallCounter()
        noop = lambda: None  # noqa: E731
        n = 2000
        t0 = time.thread_time()
        for _ in range(n):
            probe._timed("noop", noop)
        wrapped = time.thread_time() - t0
        t0 = time.thread_time()
        for _ in range(n):
            noop()
        bare = time.thread_time() - t0
        self.wrapper_cost_s = max(wrapped - bare, 0.0) / n

    def __enter__(self) -> "GLCallCounter":
        self._calibrate()
        for cls_name in _CLASSES:
            cls = getattr(moderngl, cls_name, None)
            if cls is None:
                continue
            for attr, value in list(vars(cls).items()):
                if attr in _NOT_GL or (attr.startswith("_") and not attr.startswith("__")):
                    continue
                if isinstance(value, property):
                    if value.fset is not None:
                        self._wrap_setter(cls, attr, value)
                elif callable(value) and not isinstance(value, (staticmethod, classmethod, type)):
                    self._wrap_method(cls, attr, value)
        self._wrap_uniform_write()
        # The GL entry points moderngl lacks, called through ctypes (render/gl_calls.py): glFlush hands
        # the queued work to the driver, which on llvmpipe may wait for room in its queue.
        from . import gl_calls
        self._wrap_function(gl_calls, "flush")
        for attr in ("value", "binding"):
            self._wrap_setter(moderngl.UniformBlock, attr, vars(moderngl.UniformBlock)[attr])
        return self

    def __exit__(self, *exc) -> None:
        for cls, attr, original in reversed(self._saved):
            setattr(cls, attr, original)
        self._saved.clear()
