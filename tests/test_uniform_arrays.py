"""Uniform arrays are as long as the driver keeps them, not as declared: Mesa and NVIDIA each drop the
trailing elements a shader never reads, by their own analysis (NVIDIA kept the sea's detail-map array
whole where Mesa cut it to the maps read, and refused the shorter write). ``set_uniforms`` writes
what the caller gives, cut to the program's length or padded with zeros."""

from __future__ import annotations

import numpy as np
import pytest

from igserver.render.shaders import set_uniforms

pytestmark = pytest.mark.gl

SOURCE = """#version 330
uniform vec4 a[8];   // reads a[0], a[1]: a driver may keep 2
uniform float b[4];  // reads b[0]: a driver may keep 1
uniform vec3 d[3];   // reads d[2]: all 3 kept
void main() { gl_Position = a[0] + a[1] + vec4(b[0] + d[0].x + d[2].y); }
"""


def test_arrays_longer_or_shorter_than_the_program_keeps(renderer):
    from igserver.render.context import make_current

    make_current(renderer.ctx)
    program = renderer.ctx.program(vertex_shader=SOURCE)
    kept_a, kept_b = program["a"].array_length, program["b"].array_length
    assert kept_a <= 8 and kept_b <= 4
    set_uniforms(program, {"a": np.arange(32, dtype="f4").tobytes(),  # the declared length
                           "b": [1.0, 2.0, 3.0, 4.0],
                           "d": np.ones((1, 3), "f4").tobytes()})  # one element of three
    assert np.array_equal(np.frombuffer(program["a"].read(), "f4"), np.arange(4 * kept_a, dtype="f4"))
    b = program["b"].value
    assert (b == 1.0) if kept_b == 1 else tuple(b) == (1.0, 2.0, 3.0, 4.0)[:kept_b]
    d = np.frombuffer(program["d"].read(), "f4").reshape(-1, 3)
    assert np.array_equal(d[0], [1, 1, 1]) and not d[1:].any()
