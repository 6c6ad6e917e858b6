"""Pictures of the atmosphere for docs/atmosphere.md: the dusk strip +10 .. -20 deg in 2-deg steps toward and
away from the sun (automatic exposure, eye steady state), noon fog of 300 m visibility, and a ground
fog layer (top 60 m, visibility 150 m) seen from 500 m. Run from the repository root:

    PYTHONPATH=$PWD .venv/bin/python scripts/make_atmosphere_pictures.py
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from igserver.render.renderer import Renderer
from igserver.scene.model import Scene

DOCS = Path(__file__).resolve().parents[1] / "docs"
MOONLESS = "2026-03-19T00:00:00Z"


def frame(renderer: Renderer, d: dict) -> Image.Image:
    return Image.fromarray(renderer.render(Scene.model_validate(d)).rgba[..., :3])


def main() -> int:
    DOCS.mkdir(exist_ok=True)
    r = Renderer()
    w, h = 200, 112
    elevations = list(range(10, -21, -2))  # 16 frames
    strip = Image.new("RGB", (8 * w, 4 * h))
    draw = ImageDraw.Draw(strip)
    for row, heading in enumerate((180.0, 0.0)):
        for i, el in enumerate(elevations):
            im = frame(r, {"camera": {"width": w, "height": h, "heading": heading, "pitch": 8.0, "adaptation": False,
                                      "position": [0, 0, 3]},
                           "time": {"utc": MOONLESS, "sun_override": {"elevation": el, "azimuth": 180.0}},
                           "ocean": {"enabled": True}})
            x, y = (i % 8) * w, (row * 2 + i // 8) * h
            strip.paste(im, (x, y))
            draw.text((x + 4, y + 3), f"{el:+d}° {'toward' if heading == 180.0 else 'away'}", fill=(255, 255, 255))
    strip.save(DOCS / "atmosphere_dusk_strip.jpg", quality=85)
    fog = frame(r, {"camera": {"width": 640, "height": 360, "pitch": 3.0, "position": [0, 0, 3]},
                    "time": {"sun_override": {"elevation": 50.0, "azimuth": 150.0}},
                    "atmosphere": {"visibility": 300.0},
                    "entities": [{"id": f"b{i}", "model": "box", "position": [x, 60.0 + 90 * i, 0.0],
                                  "scale": [6, 6, 12], "color": [0.3, 0.25, 0.2]}
                                 for i, x in enumerate((-8, 10, -14, 18, -5))],
                    "ocean": {"enabled": False}})
    fog.save(DOCS / "fog_noon_300m.jpg", quality=85)
    above = frame(r, {"camera": {"width": 640, "height": 360, "pitch": -12.0, "position": [0, 0, 500]},
                      "time": {"sun_override": {"elevation": 25.0, "azimuth": 200.0}},
                      "atmosphere": {"visibility": 100.0, "fog_top": 150.0},
                      "ocean": {"enabled": True}})
    above.save(DOCS / "fog_from_500m.jpg", quality=85)
    r.release()
    for name in ("atmosphere_dusk_strip.jpg", "fog_noon_300m.jpg", "fog_from_500m.jpg"):
        print(name, (DOCS / name).stat().st_size, "bytes")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
