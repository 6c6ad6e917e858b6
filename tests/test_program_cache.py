"""The program cache's look-up per exact arguments (shaders.py ProgramCache): the same defines give
the same program whatever their order, other defines another program, and a cleared cache compiles
again instead of handing back a program it no longer holds."""

from igserver.render.shaders import ProgramCache, uniform_inputs


def test_same_arguments_same_program_in_any_order(renderer):
    programs = ProgramCache(renderer.ctx)
    a = programs.program("common/fullscreen.vert.glsl", "post/tonemap.glsl", {"HALOS": 1, "MESOPIC": 1})
    assert programs.program("common/fullscreen.vert.glsl", "post/tonemap.glsl", {"HALOS": 1, "MESOPIC": 1}) is a
    assert programs.program("common/fullscreen.vert.glsl", "post/tonemap.glsl", {"MESOPIC": 1, "HALOS": 1}) is a
    assert len(programs) == 1
    b = programs.program("common/fullscreen.vert.glsl", "post/tonemap.glsl", {"HALOS": 1})
    assert b is not a and len(programs) == 2
    assert programs.program("common/fullscreen.vert.glsl", "post/tonemap.glsl") is not b
    c = programs.compute("post/meter.glsl")
    assert programs.compute("post/meter.glsl") is c and programs.compute("post/meter.glsl", {}) is c
    programs._programs.clear()  # what a table's precompute does with its own cache
    assert programs.program("common/fullscreen.vert.glsl", "post/tonemap.glsl", {"HALOS": 1}) is not b
    assert programs.compute("post/meter.glsl") is not c
    for p in (a, b, c):
        p.release()


def test_uniform_inputs_follow_the_values(renderer):
    programs = ProgramCache(renderer.ctx)
    prog = programs.program("common/fullscreen.vert.glsl", "post/tonemap.glsl")
    values = {"u_exposure_correction": 1.5, "u_hdr": 0, "u_rod_fraction": 0.25, "u_not_a_uniform": 3}
    first = uniform_inputs(prog, values)
    assert ("u_exposure_correction", 1.5) in first and all(name != "u_not_a_uniform" for name, _ in first)
    assert uniform_inputs(prog, values) == first
    assert uniform_inputs(prog, {**values, "u_exposure_correction": 2.0}) != first
    assert all(name != "u_hdr" for name, _ in uniform_inputs(prog, values, skip=("u_hdr",)))
