"""GL hazards that Mesa llvmpipe forgives and a GPU does not, checked at moderngl's boundary while the
fire, smoke, rain, sky, aerial-table and meter passes run (their compute programs and samplers).

llvmpipe runs every command to completion in submission order, so a compute dispatch whose image
stores are read without a glMemoryBarrier in between still shows the right pixels here; on a GPU
the reader may see the texture before (or while) it is written. Pixels cannot tell, so the order of
the commands is checked instead. Likewise two samplers of different types on one texture unit make a
draw or dispatch an error only where the driver's compiler counts both as active, and drivers
count differently: the programs' active samplers are checked here, and the GL error flag after the
frames."""

from __future__ import annotations

import moderngl

from igserver.scene import apply_patch, load_scene

# The commands that can consume what a dispatch wrote (moderngl class, method).
CONSUMERS = [("Context", "copy_framebuffer"), ("Framebuffer", "clear"),
             ("Framebuffer", "read"), ("Framebuffer", "read_into"), ("Texture", "read"), ("Texture", "read_into"),
             ("Texture3D", "read"), ("Texture3D", "read_into"), ("Buffer", "read"), ("Buffer", "read_into"),
             ("Texture", "build_mipmaps"), ("Texture3D", "build_mipmaps")]
# What a barrier must make visible to those: texture fetches, image loads/stores, texture and buffer
# reads by the host, storage buffers.
NEEDED_BITS = (moderngl.TEXTURE_FETCH_BARRIER_BIT | moderngl.SHADER_IMAGE_ACCESS_BARRIER_BIT
               | moderngl.TEXTURE_UPDATE_BARRIER_BIT | moderngl.BUFFER_UPDATE_BARRIER_BIT
               | moderngl.SHADER_STORAGE_BARRIER_BIT)

# GL sampler types (glGetActiveUniform); image types are a namespace of their own.
SAMPLER_TYPES = {
    0x8B5D: "sampler1D", 0x8B5E: "sampler2D", 0x8B5F: "sampler3D", 0x8B60: "samplerCube",
    0x8B61: "sampler1DShadow", 0x8B62: "sampler2DShadow", 0x8DC0: "sampler1DArray", 0x8DC1: "sampler2DArray",
    0x8DC4: "sampler2DArrayShadow", 0x8DC5: "samplerCubeShadow", 0x8DC2: "samplerBuffer",
    0x9108: "sampler2DMS", 0x900C: "samplerCubeArray", 0x8DCA: "isampler2D", 0x8DCB: "isampler3D",
    0x8DD2: "usampler2D", 0x8DD3: "usampler3D",
}


def scenes():
    """The night harbour (fire, smoke, a spot light's shadow map, halos) and the rain at the fire as a
    stream of three frames: keyframes blended, the next one modelled ahead in slices."""
    size = {"camera": {"width": 160, "height": 90}}
    yield apply_patch(load_scene("harbour_night"), size)
    rain = apply_patch(load_scene("rain_harbour"), size)
    for k in range(3):
        yield apply_patch(rain, {"time": {"sim_time": rain.time.sim_time + k / 30.0}, "host_frame": k})


def sampler_conflicts(program) -> list[list]:
    """Texture units that ``program``'s active samplers use as more than one sampler type."""
    units: dict[int, set] = {}
    for name in program:
        member = program[name]
        if isinstance(member, moderngl.Uniform) and member.gl_type in SAMPLER_TYPES:
            units.setdefault(member.value, set()).add((SAMPLER_TYPES[member.gl_type], name))
    return [sorted(s) for s in units.values() if len({t for t, _ in s}) > 1]


class CommandLog:
    """Dispatches, barriers and their possible consumers, in submission order. Each draw and dispatch
    is refused (AssertionError) when its program's samplers conflict: llvmpipe crashes on such a
    draw rather than reporting the error."""

    def __init__(self):
        self.events: list[tuple] = []
        self._saved = []

    def _hook(self, cls, method, record):
        original = getattr(cls, method)
        self._saved.append((cls, method, original))

        def hooked(obj, *args, **kwargs):
            self.events.append(record(obj, args, kwargs))
            return original(obj, *args, **kwargs)

        setattr(cls, method, hooked)

    @staticmethod
    def _checked(program, event):
        conflicts = sampler_conflicts(program)
        assert not conflicts, f"two sampler types on one texture unit: {conflicts}"
        return event

    def __enter__(self):
        self._hook(moderngl.ComputeShader, "run", lambda obj, a, k: self._checked(obj, ("dispatch", obj)))
        self._hook(moderngl.Context, "memory_barrier",
                   lambda obj, a, k: ("barrier", a[0] if a else k.get("barriers", moderngl.ALL_BARRIER_BITS)))
        self._hook(moderngl.VertexArray, "render",
                   lambda obj, a, k: self._checked(obj.program, ("use", "VertexArray.render")))
        for cls_name, method in CONSUMERS:
            self._hook(getattr(moderngl, cls_name), method, lambda obj, a, k, _n=f"{cls_name}.{method}": ("use", _n))
        return self

    def __exit__(self, *exc):
        for cls, method, original in reversed(self._saved):
            setattr(cls, method, original)


def unfenced(events) -> list[str]:
    """Commands that run after a dispatch with no barrier (of the needed bits) in between. A dispatch of
    the same program may follow (a program filling a table in chunks, or several buffers)."""
    problems, pending = [], None
    for i, event in enumerate(events):
        if event[0] == "barrier":
            if event[1] & NEEDED_BITS == NEEDED_BITS:
                pending = None
        elif event[0] == "dispatch":
            if pending is not None and pending is not event[1]:
                problems.append(f"#{i}: a dispatch of another program after an unfenced dispatch")
            pending = event[1]
        elif pending is not None:
            problems.append(f"#{i}: {event[1]} after an unfenced dispatch")
    return problems


def test_unfenced_dispatch_is_found():
    """The check itself: a missing barrier between a dispatch and a draw, or a barrier without the
    texture-fetch bit, is reported; one with it, or chunks of one program, is not."""
    a, b = object(), object()
    ok = [("dispatch", a), ("dispatch", a), ("barrier", moderngl.ALL_BARRIER_BITS), ("use", "VertexArray.render")]
    assert unfenced(ok) == []
    assert unfenced([("dispatch", a), ("use", "VertexArray.render")])
    assert unfenced([("dispatch", a), ("dispatch", b), ("barrier", moderngl.ALL_BARRIER_BITS)])
    assert unfenced([("dispatch", a), ("barrier", moderngl.SHADER_IMAGE_ACCESS_BARRIER_BIT), ("use", "Texture.read")])


def test_every_dispatch_is_fenced_before_use(renderer):
    """Each compute dispatch (volume modelling, smoke shadows, rain lighting, the sky-view and aerial
    tables, the exposure meter) is followed by glMemoryBarrier before anything can read its output:
    a draw, a read-back, a clear, a blit, a mipmap build or another program's dispatch."""
    with CommandLog() as log:
        for scene in scenes():
            renderer.render(scene)
    dispatches = sum(1 for e in log.events if e[0] == "dispatch")
    assert dispatches >= 6, log.events  # fire and smoke keyframes, shadows, meter at least
    assert unfenced(log.events) == []


def test_samplers_and_error_flag(renderer):
    """No draw or dispatch of the frames binds two sampler types to one texture unit (GL refuses it
    where the driver counts both samplers active; llvmpipe crashes), no program compiled so far has
    such a pair, and the frames raise no GL error."""
    ctx = renderer.ctx
    ctx.error  # noqa: B018 (reading the flag clears what earlier tests left)
    with CommandLog():
        for scene in scenes():
            renderer.render(scene)
    assert ctx.error == "GL_NO_ERROR"
    assert [c for program in renderer.programs for c in sampler_conflicts(program)] == []
