"""Pictures of the example scenes for the README and docs/ (docs/*.jpg), each the scene file rendered as it stands
(its own time, weather and preset). The atmosphere pictures have their own script
(make_atmosphere_pictures.py). Run from the repository root:

    PYTHONPATH=$PWD .venv/bin/python scripts/make_readme_pictures.py [name ...]
"""

from __future__ import annotations

import sys
from pathlib import Path

from PIL import Image

from igserver.render.renderer import Renderer
from igserver.scene import apply_patch
from igserver.scene.files import load_scene

DOCS = Path(__file__).resolve().parents[1] / "docs"

BRIDGE = {"camera": {"position": [0.0, 0.0, 15.0], "pitch": -3.0}, "time": {"sim_time": 100.0}}
BRIDGE_ACROSS = {"camera": {"position": [0.0, 0.0, 15.0], "heading": 30.0, "pitch": -3.0}, "time": {"sim_time": 100.0}}
AIR = {"camera": {"position": [0.0, 0.0, 300.0], "pitch": -20.0}, "time": {"sim_time": 100.0}}
SHORE = {"camera": {"position": [405.0, -200.0, 6.0], "heading": 350.0, "pitch": -8.0}, "time": {"sim_time": 100.0}}

# picture -> (scene, width, height[, patch]): the patch puts the camera on a ship's bridge, in the air or on the beach
PICTURES = {
    "demo.jpg": ("demo", 800, 450),
    "surfaces_noon.jpg": ("harbour_noon", 640, 360),
    "surfaces_dusk.jpg": ("demo", 640, 360),
    "surfaces_night.jpg": ("harbour_night", 640, 360),
    "rain_harbour.jpg": ("rain_harbour", 640, 360),
    "snow.jpg": ("snow", 640, 360),
    "water_calm_dawn.jpg": ("sea_calm_dawn", 640, 360),
    "water_beaufort5.jpg": ("sea_beaufort5", 640, 360),
    "water_beaufort9.jpg": ("sea_beaufort9", 640, 360),
    "water_beach.jpg": ("sea_beach", 640, 360),
    "water_beaufort9_bridge.jpg": ("sea_beaufort9", 640, 360, BRIDGE),
    "water_beaufort9_bridge_across.jpg": ("sea_beaufort9", 640, 360, BRIDGE_ACROSS),
    "water_beaufort9_300m.jpg": ("sea_beaufort9", 640, 360, AIR),
    "water_beaufort5_bridge.jpg": ("sea_beaufort5", 640, 360, BRIDGE),
    "water_beach_shore.jpg": ("sea_beach", 640, 360, SHORE),
    "water_harbour_fire.jpg": ("sea_harbour_fire", 640, 360),
}


def main(names: list[str]) -> int:
    renderer = Renderer()
    for picture, (scene_name, width, height, *patch) in PICTURES.items():
        if names and picture not in names and scene_name not in names:
            continue
        scene = apply_patch(load_scene(scene_name), patch[0]) if patch else load_scene(scene_name)
        scene = scene.model_copy(update={"camera": scene.camera.model_copy(update={"width": width, "height": height})})
        rgba = renderer.render(scene).rgba
        Image.fromarray(rgba[..., :3]).save(DOCS / picture, quality=88)
        print(f"docs/{picture}: {scene_name} {width}x{height}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
