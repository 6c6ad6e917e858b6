"""The combined quality report: every study module is found, the report has a table per
pipeline and a PNG plot of error against ms with the presets marked."""

from __future__ import annotations

from PIL import Image

from igserver.cli import main
from igserver.quality.report import Point, Study, study_modules, write_report


def test_every_study_module_is_found():
    names = study_modules()
    assert {"sky", "volumes"} <= set(names) and "report" not in names and "reference_sky" not in names


def test_report_has_tables_and_plots(tmp_path):
    study = Study("volumes", "RMSE", "ms", [
        Point("steps", "steps=16", 9.0, 10.0), Point("steps", "steps=48", 5.0, 20.0, None, {"lowpass": 2.0}),
        Point("preset", "medium", 5.0, 20.0, "medium"), Point("scale", "scale=2", 6.0, 8.0)], ["a note"], "llvmpipe")
    path = write_report([study], tmp_path, {"weather": "no study() for the combined report yet"})
    text = path.read_text()
    assert "## volumes" in text and "![volumes: error against ms](volumes.png)" in text
    assert "**medium**" in text and "| steps | steps=48 | 5 | 20 | 2 |" in text and "## weather" in text
    with Image.open(tmp_path / "volumes.png") as png:
        assert png.size[0] > 300 and png.getextrema()[0][0] < 50  # drawn, with dark lines on white
    assert (tmp_path / "report.json").exists()


def test_quality_without_a_study_name_takes_report_flags(tmp_path, capsys):
    # --only with an unknown study: the run fails cleanly and says so in the report.
    assert main(["quality", "--only", "no_such_study", "--out", str(tmp_path)]) == 1
    assert "no_such_study" in (tmp_path / "report.md").read_text()


def test_water_study_marks_the_presets_on_its_curves(monkeypatch):
    # The sea's points for the combined report: one curve per knob and the three presets as the renderer
    # runs them (tiny frames here). `medium` is the scene's own settings: the same picture as the
    # default point; `low` draws the coarse mesh: fewer triangles, more error.
    import math

    from igserver.quality import water

    parse = water.parse_args
    monkeypatch.setattr(water, "parse_args", lambda argv: parse([*argv, "--size", "160x90", "--lod", "1",
                                                               "--detail", "128", "--spacing", "8"]))
    study = water.study(quick=True)
    assert study.pipeline == "water" and study.device
    by = {(p.knob, p.preset or p.setting): p for p in study.points}
    assert {p.preset for p in study.points if p.preset} == {"low", "medium", "high"}
    assert not any(p.knob == "wave_count" for p in study.points)
    assert {"lod_error", "detail_resolution", "spacing", "mesh", "atmosphere"} <= {p.knob for p in study.points}
    assert all(math.isfinite(p.error) and p.error >= 0 and p.ms > 0 for p in study.points)
    medium, low = by[("preset", "medium")], by[("preset", "low")]
    assert medium.error == by[("lod_error", "lod_error=1.0")].error
    assert low.extra["triangles"] < medium.extra["triangles"] and low.error > medium.error


def test_without_matplotlib_the_report_says_which_extra_to_install(tmp_path, monkeypatch, capsys):
    # matplotlib is the optional extra igserver[quality]: the server runs without it, and the report
    # refuses up front (before any study runs) with the install line.
    import sys

    import pytest

    from igserver.quality.report import plot_study

    monkeypatch.setitem(sys.modules, "matplotlib", None)  # import matplotlib now raises ImportError
    assert main(["quality", "--only", "no_such_study", "--out", str(tmp_path)]) == 2
    assert "install igserver[quality]" in capsys.readouterr().err and not (tmp_path / "report.md").exists()
    with pytest.raises(ModuleNotFoundError, match=r"igserver\[quality\]"):
        plot_study(Study("volumes", "RMSE", "ms", []), tmp_path / "volumes.png")


def test_the_server_installs_and_runs_without_matplotlib():
    # matplotlib is the optional extra igserver[quality], pinned like the rest; the server, the renderer
    # and the report module load without importing it (a fresh interpreter: nothing imported before)
    import subprocess
    import sys
    import tomllib
    from pathlib import Path

    project = tomllib.loads((Path(__file__).resolve().parents[1] / "pyproject.toml").read_text())["project"]
    assert not [d for d in project["dependencies"] if d.startswith("matplotlib")]
    assert [d for d in project["optional-dependencies"]["quality"] if d.startswith("matplotlib==")]
    code = ("import sys, igserver.cli, igserver.protocol.app, igserver.render.renderer, igserver.render.worker, "
            "igserver.quality.report; print(sorted(m for m in sys.modules if m.startswith('matplotlib')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=120)
    assert out.stdout.strip() == "[]"
