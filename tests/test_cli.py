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
    from igserver.source_id import source_id

    assert f"source {source_id()}" in proc.stdout  # which tree made the picture


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
    from igserver.source_id import source_id

    assert report["source"] == source_id()
    run0 = report["runs"][0]
    assert run0["pass_ms"]["sky"]["median"] > 0
    # CPU split per pass: the calling thread's share and the other threads' (llvmpipe's workers).
    assert set(run0["pass_cpu_ms"]) == set(run0["passes"])
    for split in run0["pass_cpu_ms"].values():
        assert split["calling_thread"] >= 0.0 and split["workers"] >= -0.5  # process - thread clock: ~µs noise
    assert run0["pass_cpu_ms"]["sky"]["calling_thread"] + run0["pass_cpu_ms"]["sky"]["workers"] > 0.0
    assert "cpu ms calling thread/workers: sky" in proc.stdout


def test_unknown_quality_study_lists_the_studies(capsys):
    from igserver.cli import main

    assert main(["quality", "nosuch"]) == 2
    err = capsys.readouterr().err
    assert "no quality study named 'nosuch'" in err
    for study in ("sky", "volumes", "water", "surfaces"):
        assert study in err
    listed = err.split("studies:")[-1].split("(")[0]
    assert "report" not in listed  # the report is not a study


def test_bench_resolution_typo_is_a_usage_message(capsys):
    import pytest

    from igserver.cli import main

    with pytest.raises(SystemExit) as info:
        main(["bench", "--resolutions", "64by36"])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert "usage: igserver bench" in err and "--resolutions" in err and "WIDTHxHEIGHT" in err
    assert "invalid literal for int()" not in err
    with pytest.raises(SystemExit):
        main(["bench", "--resolutions", "640x360,0x10"])
    assert "640x360" in capsys.readouterr().err
