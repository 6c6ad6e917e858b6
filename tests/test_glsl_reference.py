"""Every shader variant the example scenes compile, and their rehearsals (render/rehearsal.py), passes the
Khronos reference front end (glslangValidator, GLSL 4.50 for OpenGL): the nearest this machine has to a
second vendor's compiler. Mesa accepts some GLSL that others refuse (implicit conversions, a missing
precision in an overload, a name a driver reserves); a shader that only Mesa compiles would fail on the
GPUs the IG is meant for. scripts/test.sh installs the tool (Debian's glslang-tools) when run as root."""

from __future__ import annotations

import concurrent.futures
import shutil
import subprocess
from pathlib import Path

import pytest

from igserver.render import shaders
from igserver.scene import apply_patch, load_scene

SCENES = sorted(p.stem for p in (Path(__file__).resolve().parents[1] / "igserver" / "scenes").glob("*.toml"))
# Scenes also rehearsed holding a frame rate: between them every pass at every scale and preset (the
# variants that follow the pixel count and the knobs), without the time of all scenes held.
HELD_SCENES = ("demo", "harbour_night", "snow")
STAGE_SUFFIX = {"VERTEX": "vert", "FRAGMENT": "frag", "COMPUTE": "comp"}


def variant_sources(monkeypatch) -> dict[tuple, str]:
    """(file, stage, defines) -> assembled source of every program a fresh renderer compiles for the
    example scenes and their rehearsals (as they are, and some holding a frame rate)."""
    from igserver.render.renderer import Renderer

    seen: dict[tuple, str] = {}
    assemble = shaders.assemble

    def recording(path, stage, defines=None):
        source = assemble(path, stage, defines)
        seen[(path, stage, tuple(sorted((defines or {}).items())))] = source
        return source

    monkeypatch.setattr(shaders, "assemble", recording)
    renderer = Renderer()
    try:
        renderer.programs.compute("common/gpu_busy.comp.glsl")  # the bench's GPU head start (bench_gpu.py)
        for name in SCENES:
            scene = apply_patch(load_scene(name), {"camera": {"width": 32, "height": 18}})
            renderer.render(scene)
            renderer.rehearse(scene)
            if name in HELD_SCENES:  # every scale and preset a controller may draw (rehearsal_draws)
                renderer.rehearse(apply_patch(scene, {"quality": {"target_fps": 25.0, "preset": "auto"}}))
    finally:
        renderer.release()
    return seen


@pytest.mark.skipif(shutil.which("glslangValidator") is None,
                    reason="glslangValidator not installed (apt-get install glslang-tools; scripts/test.sh does as root)")
def test_every_variant_passes_the_reference_compiler(monkeypatch, tmp_path):
    sources = variant_sources(monkeypatch)
    assert len(sources) > 200 and {stage for _, stage, _ in sources} == set(STAGE_SUFFIX)
    files = []
    for i, ((path, stage, _), source) in enumerate(sources.items()):
        f = tmp_path / f"{i}_{Path(path).stem}.{STAGE_SUFFIX[stage]}"
        f.write_text(source)
        files.append(f)

    def check(f: Path) -> str | None:
        out = subprocess.run(["glslangValidator", str(f)], capture_output=True, text=True, timeout=60)
        return None if out.returncode == 0 else f"{f.name}:\n{out.stdout[-1200:]}"

    with concurrent.futures.ThreadPoolExecutor(max_workers=2) as pool:
        refused = [r for r in pool.map(check, files) if r is not None]
    assert not refused, f"{len(refused)} of {len(files)} refused:\n" + "\n".join(refused[:3])
