"""Pictures of fire and light for the README (docs/images/*.jpg): the pool fire by day and by night at 8 m and
50 m, an oil (diesel) fire's black smoke beside a wood fire's grey smoke, a fog top seen from above (thin and
thick), the built-in box at noon and by the fire at night, and a dusk strip from +5 to -12 deg. Each is a
montage of small frames with a label in each. Run from the repository root:

    PYTHONPATH=$PWD .venv/bin/python scripts/make_fire_light_pictures.py [name ...]
"""

from __future__ import annotations

import sys
from pathlib import Path

from PIL import Image, ImageDraw

from igserver.render.renderer import Renderer
from igserver.scene import apply_patch
from igserver.scene.files import load_scene

IMAGES = Path(__file__).resolve().parents[1] / "docs" / "images"
DAY = "2026-09-15T10:00:00Z"  # local noon at the night_fire scene's place (30.3 deg E), sun ~31 deg up
W, H = 480, 270


def frame(renderer: Renderer, scene_name: str, patch: dict, w: int = W, h: int = H) -> Image.Image:
    scene = load_scene(scene_name)
    patch = {**patch, "camera": {**patch.get("camera", {}), "width": w, "height": h}}
    return Image.fromarray(renderer.render(apply_patch(scene, patch)).rgba[..., :3])


def montage(frames: list[tuple[Image.Image, str]], columns: int) -> Image.Image:
    w, h = frames[0][0].size
    rows = (len(frames) + columns - 1) // columns
    out = Image.new("RGB", (columns * w, rows * h))
    draw = ImageDraw.Draw(out)
    for i, (im, label) in enumerate(frames):
        x, y = (i % columns) * w, (i // columns) * h
        out.paste(im, (x, y))
        draw.text((x + 6, y + 4), label, fill=(0, 0, 0))
        draw.text((x + 5, y + 3), label, fill=(255, 255, 255))
    return out


def fire_effect(scene_name: str, **fields) -> list[dict]:
    effects = load_scene(scene_name).model_dump(mode="json")["effects"]
    effects[0].update(fields)
    return effects


def pool_fire(r: Renderer) -> Image.Image:
    shots = []
    for when, utc in (("day", DAY), ("night", None)):
        for distance, pitch in ((8.0, 12.0), (50.0, 6.0)):
            patch = {"camera": {"position": [0.0, -distance, 1.7], "pitch": pitch}}
            if utc:
                patch["time"] = {"utc": utc}
            shots.append((frame(r, "night_fire", patch), f"3 m oil pool fire, {when}, {distance:.0f} m"))
    return montage(shots, 2)


def smoke_by_fuel(r: Renderer) -> Image.Image:
    shots = []
    for fuel, label in (("oil", "diesel (fuel oil): black smoke"), ("wood", "wood: grey smoke")):
        patch = {"time": {"utc": DAY}, "camera": {"position": [0.0, -32.0, 1.7], "pitch": 22.0},
                 "effects": fire_effect("night_fire", fuel=fuel)}
        shots.append((frame(r, "night_fire", patch), label))
    return montage(shots, 2)


def fog_from_above(r: Renderer) -> Image.Image:
    shots = []
    for visibility, top, label in ((300.0, 150.0, "fog 150 m deep, visibility 300 m (optical depth 2)"),
                                   (100.0, 300.0, "stratus 300 m deep, visibility 100 m (optical depth 12)")):
        patch = {"atmosphere": {"visibility": visibility, "fog_top": top}, "time": {"utc": "2026-06-21T11:40:00Z"},
                 "camera": {"position": [0.0, 0.0, 500.0 if top < 300 else 650.0], "pitch": -20.0}}
        shots.append((frame(r, "sea_beaufort5", patch), label))
    return montage(shots, 2)


def box_noon_and_fire(r: Renderer) -> Image.Image:
    camera = {"position": [-2.0, -10.0, 2.2], "heading": 25.0, "pitch": 4.0}
    return montage([(frame(r, "night_fire", {"time": {"utc": DAY}, "camera": camera}), "the box at noon"),
                    (frame(r, "night_fire", {"camera": camera}), "the box by the fire at night")], 2)


def dusk_strip(r: Renderer) -> Image.Image:
    shots = []
    for el in (5.0, 2.0, 0.0, -2.0, -4.0, -6.0, -8.0, -10.0, -12.0):
        patch = {"time": {"sun_override": {"elevation": el, "azimuth": 300.0}},
                 "camera": {"position": [0.0, 0.0, 15.0], "heading": 300.0, "pitch": 8.0, "fov_y": 50.0}}
        shots.append((frame(r, "sea_calm_dawn", patch, 320, 180), f"sun {el:+.0f} deg"))
    return montage(shots, 3)


PICTURES = {"pool_fire.jpg": pool_fire, "smoke_by_fuel.jpg": smoke_by_fuel, "fog_from_above.jpg": fog_from_above,
            "box_noon_and_fire.jpg": box_noon_and_fire, "dusk_strip.jpg": dusk_strip}


def main(names: list[str]) -> int:
    IMAGES.mkdir(parents=True, exist_ok=True)
    renderer = Renderer()
    for name, make in PICTURES.items():
        if names and name not in names:
            continue
        make(renderer).save(IMAGES / name, quality=90)
        print(f"docs/images/{name}: {(IMAGES / name).stat().st_size // 1024} KB")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
