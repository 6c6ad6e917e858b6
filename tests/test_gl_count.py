"""The GL call counter (render/gl_count.py) and what ``igserver bench`` reports from it."""

import moderngl
import numpy as np
import pytest

from igserver.bench import bench_scene, markdown_table
from igserver.bench_gpu import PassTimers, timer_queries_unusable
from igserver.render.gl_count import GLCallCounter

from helpers import tiny

VERTEX = """#version 330
in vec2 in_pos;
void main() { gl_Position = vec4(in_pos, 0.0, 1.0); }
"""
FRAGMENT = """#version 330
uniform float u_a;
uniform vec2 u_b;
uniform vec3 u_c;
uniform sampler2D u_tex;
out vec4 colour;
void main() { colour = vec4(u_a + u_b.x + u_c.y, 0.0, 0.0, 1.0) + texture(u_tex, vec2(0.5)); }
"""


@pytest.fixture()
def tiny_program(renderer):
    ctx = renderer.ctx
    program = ctx.program(vertex_shader=VERTEX, fragment_shader=FRAGMENT)
    vbo = ctx.buffer(np.array([-1, -1, 3, -1, -1, 3], dtype="f4").tobytes())
    vao = ctx.vertex_array(program, [(vbo, "2f", "in_pos")])
    texture = ctx.texture((2, 2), 4)
    yield program, vao, texture
    for obj in (vao, vbo, program, texture):
        obj.release()


def _moderngl_attributes() -> dict:
    return {(name, attr): value for name in dir(moderngl) if isinstance(getattr(moderngl, name), type)
            for attr, value in vars(getattr(moderngl, name)).items()}


def test_a_known_sequence_is_counted_exactly(tiny_program):
    program, vao, texture = tiny_program
    with GLCallCounter() as calls:
        program["u_a"].value = 1.0
        program["u_b"].value = (2.0, 3.0)
        program["u_c"].value = (4.0, 5.0, 6.0)
        texture.use(0)
        vao.render()
    assert calls.total == 5, dict(calls.by_name)
    for uniform in ("u_a", "u_b", "u_c"):  # one write each, named by the uniform
        assert sum(n for name, n in calls.by_name.items() if uniform in name) == 1, dict(calls.by_name)
    assert calls.by_name["Texture.use"] == 1 and calls.by_name["VertexArray.render"] == 1
    assert calls.created() == 0
    assert calls.gl_cpu_s > 0 and calls.wrapper_cost_s > 0
    assert calls.overhead_s == pytest.approx(5 * calls.wrapper_cost_s)


def test_objects_made_in_the_block_are_counted(renderer):
    with GLCallCounter() as calls:
        buffer = renderer.ctx.buffer(reserve=16)
        buffer.write(b"\0" * 16)
        buffer.release()  # object lifetime, not GL work of a frame
    assert calls.created() == 1 and calls.total == 2, dict(calls.by_name)


def test_moderngl_is_restored_after_the_block_even_on_an_exception(tiny_program):
    program, vao, _ = tiny_program
    before = _moderngl_attributes()
    with pytest.raises(RuntimeError):
        with GLCallCounter():
            program["u_a"].value = 1.0
            raise RuntimeError("inside the block")
    assert _moderngl_attributes() == before
    with GLCallCounter() as calls:
        pass
    vao.render()  # after the block: not counted
    assert calls.total == 0


def test_bench_reports_python_ms_gl_calls_objects_and_fps_in_flight(renderer):
    row = bench_scene(renderer, tiny(), frames=2, warmup=1, gpu_timer=timer_queries_unusable(renderer))
    assert row["gl_calls"] > 0 and row["gl_objects_created"] == 0
    assert 0 < row["python_ms"]["median"] < row["frame_ms"]["median"] * 4
    assert row["fps_in_flight"] > 0 and row["fps_sync"] > 0
    if "llvmpipe" in renderer.caps.renderer:  # no GPU clock: said why, no GPU column
        assert row["gpu_timer"] == "llvmpipe has no GPU clock" and "gpu_pass_ms" not in row
    else:
        assert set(row["gpu_pass_ms"]) <= set(row["passes"])
    report = {"runs": [dict(row, scene="tiny", resolution="64x36", preset="medium")]}
    head, _, line = markdown_table(report).splitlines()[:3]
    for column in ("fps in flight", "Python ms", "GL calls", "GL objects made"):
        assert column in head
    assert f"| {row['gl_calls']} |" in line


def test_bench_python_ms_is_the_python_a_frame_runs(renderer, monkeypatch):
    # A pass made to run 4 ms more of Python a frame: the bench's Python ms grows by those 4 ms
    # (within 1.5 ms: two runs of frames on a shared machine).
    import time

    scene = tiny()
    before = bench_scene(renderer, scene, frames=6, warmup=1, gpu_timer="not asked")["python_ms"]["median"]
    sky = renderer.graph.passes["sky"]
    execute = sky.execute

    def slower(*args, **kwargs):
        end = time.thread_time() + 0.004
        while time.thread_time() < end:
            pass
        return execute(*args, **kwargs)

    monkeypatch.setattr(sky, "execute", slower)
    after = bench_scene(renderer, scene, frames=6, warmup=1, gpu_timer="not asked")["python_ms"]["median"]
    assert after - before == pytest.approx(4.0, abs=1.5), (before, after)


def test_pass_timers_bracket_each_pass_and_leave_the_passes_as_they_were(renderer):
    scene = tiny()
    with PassTimers(renderer) as timers:
        result = renderer.render(scene)
        gpu_ms = timers.read()
    assert list(gpu_ms) == [n for n in result.passes if n in gpu_ms] and set(gpu_ms) == set(result.passes)
    assert all(ms >= 0 for ms in gpu_ms.values())  # llvmpipe's read 0
    assert all("execute" not in vars(p) for p in renderer.graph.passes.values())


class _FakeHeadStart:
    """A head start on a fake GPU clock: the busy job ends ``lead_ms`` after it is given, and the host
    needs ``host_ms`` to issue a frame's passes."""

    def __init__(self, host_ms: float):
        self.host_ms, self.now_ns, self.end_ns, self.given = host_ms, 0, 0, []

    def give(self, ms: float) -> None:
        self.given.append(ms)
        self.now_ns += 1_000_000_000
        self.end_ns = self.now_ns + int(ms * 1e6)

    def clock_ns(self) -> int:  # read as each pass has been issued: the host's work, spread over them
        return self.now_ns + int(self.host_ms * 1e6)

    def finished_ns(self) -> int:
        return self.end_ns


def test_a_frame_issued_after_the_gpu_caught_up_is_drawn_again_behind_a_longer_head_start(renderer):
    from igserver.bench_gpu import queued_gpu_pass_ms

    scenes = [tiny(), tiny()]
    head = _FakeHeadStart(host_ms=30.0)
    row = queued_gpu_pass_ms(renderer, scenes, host_ms=1.0, head=head)
    # 1.25 x 1 + 2 = 3.25 -> the 5 ms floor, then 10, 20, 40 (> 30: confirmed); the second frame starts at 40
    assert head.given == [5.0, 10.0, 20.0, 40.0, 40.0]
    assert row["gpu_head_start_ms"] == 40.0 and row["gpu_frames_redrawn"] == 3 and row["gpu_frames_unconfirmed"] == 0
    assert set(row["gpu_pass_ms"]) == set(renderer.render(tiny()).passes)
    assert all("execute" not in vars(p) for p in renderer.graph.passes.values())
    # A host slower than the longest head start: drawn at it once more, reported unconfirmed, no loop.
    head = _FakeHeadStart(host_ms=5000.0)
    row = queued_gpu_pass_ms(renderer, [tiny()], host_ms=400.0, head=head)
    assert head.given == [502.0, 1000.0] and row["gpu_frames_unconfirmed"] == 1


def test_gpu_pass_times_say_how_they_were_taken(renderer):
    from igserver.bench_gpu import gpu_pass_ms

    row = gpu_pass_ms(renderer, [tiny()], host_ms=5.0)
    assert set(row["gpu_pass_ms"]) == set(renderer.render(tiny()).passes)
    if "llvmpipe" in renderer.caps.renderer:  # its loops stop at 65,535 steps: no head start to give
        assert row["gpu_timing"].startswith("as issued, GPU idling included (no head start: the busy job")
    else:
        assert row["gpu_timing"] == "queued behind a head start" and row["gpu_head_start_ms"] >= 5.0


def test_a_head_start_that_fails_leaves_the_pass_times_as_issued(renderer, monkeypatch):
    """The GPU session is short: a driver that lacks what the head start needs must still give figures."""
    from igserver import bench_gpu

    def broken(_renderer):
        raise RuntimeError("no timestamp queries")

    monkeypatch.setattr(bench_gpu, "GPUHeadStart", broken)
    row = bench_gpu.gpu_pass_ms(renderer, [tiny()], host_ms=5.0)
    assert row["gpu_timing"] == "as issued, GPU idling included (no head start: RuntimeError: no timestamp queries)"
    assert set(row["gpu_pass_ms"]) == set(renderer.render(tiny()).passes)
