"""``igserver quality water``'s foam and surf rows (igserver/quality/water_surf.py): each measures the
drawn sea against its field reference and reports the ratio with the water pass's cost."""

from __future__ import annotations

import math

from igserver.quality import water, water_surf


def test_whitecap_and_swash_rows_measure_against_their_references(renderer):
    """Whitecaps at Beaufort 5 within x1.5 of Monahan & O'Muircheartaigh (1980) from both views (the
    bound the foam tests hold); the swash's run-up line within 0.4-1.2 of Stockdon et al. (2006)'s R2
    and wet sand under 0.8 of dry (0.6 in beach photographs), each row with a measured water ms."""
    rows = water_surf.whitecap_rows(renderer, [9.4], (160, 90), frames=1)
    rows += water_surf.swash_row(renderer, (160, 90), frames=1)
    by_part = {(r["part"], r["view"]): r for r in rows}
    assert {p for p, _ in by_part} == {"whitecaps", "swash run-up", "wet / dry sand"}
    for (part, view), r in by_part.items():
        assert math.isfinite(r["measured"]) and r["ms"] > 0.0, (part, view, r)
        if part == "whitecaps":
            assert 1 / 1.5 < r["ratio"] < 1.5, (view, r)
    assert 0.4 < by_part[("swash run-up", "sea_beach from the sand")]["ratio"] < 1.2
    assert by_part[("wet / dry sand", "sea_beach from the sand")]["measured"] < 0.8
    table = "\n".join(water_surf.markdown(rows))
    assert table.count("| whitecaps |") == 2 and "| swash run-up |" in table


def test_water_report_carries_the_surf_table(tmp_path, monkeypatch):
    """The report written by ``igserver quality water`` ends with the foam and surf table."""
    rows = [{"part": "whitecaps", "view": "bridge, wind 9.4 m/s", "measured": 0.007, "reference": 0.008,
             "ratio": 0.875, "ms": 12.0}]
    base = {"knob": "preset", "value": "medium", "wave_count": 24, "lod_error": 1.0, "detail_resolution": 128,
            "ms": 20.0, "triangles": 1, "finest_spacing_m": 1.0, "rmse": 1.0, "lowpass": 0.4, "near_rms_cm": 0.1,
            "near_max_cm": 0.5, "far_rms_cm": 1.0, "far_max_cm": 2.0, "hs": 2.0, "mss": 0.05}
    args = water.parse_args(["--out", str(tmp_path / "q.md")])
    water.write_markdown(args, {"rows": [base], "surf": rows, "size": (160, 90), "position": (0, 0, 12),
                                "reference_ms": 80.0, "default_spacing": 8.0, "renderer": "test",
                                "preset_knobs": {}})
    text = (tmp_path / "q.md").read_text()
    assert "| whitecaps | bridge, wind 9.4 m/s | 0.70 % | 0.80 % | 0.88 | 12.0 |" in text
