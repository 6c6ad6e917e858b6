import math

import pytest
from pydantic import ValidationError

from igserver.scene import Scene, apply_patch, dumps_scene, load_scene, patch_from_assignments
from igserver.scene.files import SCENES_DIR


def error_paths(exc: ValidationError) -> list[str]:
    return [".".join(str(p) for p in e["loc"]) for e in exc.errors()]


def test_defaults_are_valid():
    scene = Scene()
    assert scene.camera.width == 640 and scene.atmosphere.visibility == 30_000.0


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf])
def test_non_finite_rejected_naming_the_field(value):
    with pytest.raises(ValidationError) as info:
        Scene.model_validate({"camera": {"pitch": value}})
    assert "camera.pitch" in error_paths(info.value)


@pytest.mark.parametrize(
    "patch, path",
    [
        ({"camera": {"pitch": 91}}, "camera.pitch"),
        ({"atmosphere": {"visibility": 10}}, "atmosphere.visibility"),
        ({"camera": {"width": 10_000}}, "camera.width"),
        ({"weather": {"precipitation": {"rate": -1}}}, "weather.precipitation.rate"),
        ({"camera": {"position": [0, 0, 1e9]}}, "camera.position.2"),
        ({"effects": [{"id": "f", "diameter": -2}]}, "effects.0.diameter"),
        ({"camera": {"pitch": "up"}}, "camera.pitch"),
        ({"camera": {"zoom": 2}}, "camera.zoom"),
        ({"time": {"utc": "yesterday"}}, "time.utc"),
    ],
)
def test_bad_values_rejected_with_their_path(patch, path):
    with pytest.raises(ValidationError) as info:
        apply_patch(Scene(), patch)
    assert path in error_paths(info.value)


def test_cross_field_rules():
    with pytest.raises(ValidationError):
        Scene.model_validate({"camera": {"near": 10, "far": 5}})
    with pytest.raises(ValidationError):
        Scene.model_validate({"effects": [{"id": "a"}, {"id": "a"}]})
    with pytest.raises(ValidationError):
        Scene.model_validate({"camera": {"frustum": {"left": 10, "right": -10}}})


def test_patch_merges_and_never_half_applies():
    scene = Scene()
    merged = apply_patch(scene, {"camera": {"pitch": 10}, "weather": {"wind_speed": 12}})
    assert merged.camera.pitch == 10 and merged.weather.wind_speed == 12
    assert merged.camera.heading == scene.camera.heading  # untouched sibling kept
    with pytest.raises(ValidationError):
        apply_patch(merged, {"camera": {"pitch": 20}, "weather": {"wind_speed": 999}})
    assert merged.camera.pitch == 10  # the valid half of a rejected patch did not land
    assert scene.camera.pitch == 0


def test_set_assignments():
    patch = patch_from_assignments(["camera.pitch=10", "camera.fov_y=4", "time.utc=2027-03-14T06:10:00Z", "effects=[]"])
    scene = apply_patch(Scene(), patch)
    assert scene.camera.pitch == 10 and scene.camera.fov_y == 4 and scene.effects == []
    assert scene.time.utc.year == 2027 and scene.time.utc.hour == 6


@pytest.mark.parametrize("name", sorted(p.stem for p in SCENES_DIR.glob("*.toml")))
def test_scene_files_round_trip(name, tmp_path):
    scene = load_scene(name)
    path = tmp_path / f"{name}.toml"
    path.write_text(dumps_scene(scene))
    assert load_scene(path) == scene


def test_required_example_scenes_exist():
    names = {p.stem for p in SCENES_DIR.glob("*.toml")}
    assert {"demo", "clear_noon_ocean", "sky_only", "night_fire", "high_altitude"} <= names


def test_scene_format_reference_is_current():
    from pathlib import Path

    from igserver.scene.reference import markdown_reference

    doc = Path(__file__).resolve().parents[1] / "docs" / "scene-format.md"
    assert doc.read_text() == markdown_reference(), "regenerate: python -m igserver.scene.reference > docs/scene-format.md"
