"""The CLI as a user runs it: render a scene file to a PNG, with --set overrides and clear errors."""

import subprocess
import sys

from PIL import Image


def run(*args):
    return subprocess.run([sys.executable, "-m", "igserver.cli", *args], capture_output=True, text=True, timeout=300)


def test_render_writes_png_with_overrides(tmp_path):
    out = tmp_path / "frame.png"
    proc = run("render", "--scene", "sky_only", "--out", str(out), "--width", "80", "--height", "48",
               "--set", "camera.pitch=10", "--set", "time.utc=2027-03-14T06:10:00Z")
    assert proc.returncode == 0, proc.stderr
    image = Image.open(out)
    assert image.size == (80, 48)
    assert "passes sky post" in proc.stdout


def test_bad_override_is_a_clear_error(tmp_path):
    proc = run("render", "--scene", "sky_only", "--out", str(tmp_path / "x.png"), "--set", "camera.pitch=400")
    assert proc.returncode == 2 and "camera.pitch" in proc.stderr
    assert not (tmp_path / "x.png").exists()
    proc = run("render", "--scene", "no_such_scene", "--out", str(tmp_path / "x.png"))
    assert proc.returncode == 2 and "not found" in proc.stderr


def test_bench_prints_per_pass_medians(tmp_path):
    proc = run("bench", "--scenes", "sky_only", "--resolutions", "64x36", "--frames", "3",
               "--json", str(tmp_path / "b.json"))
    assert proc.returncode == 0, proc.stderr
    assert "renderer:" in proc.stdout and "sky" in proc.stdout
    import json

    report = json.loads((tmp_path / "b.json").read_text())
    assert report["runs"][0]["pass_ms"]["sky"]["median"] > 0
