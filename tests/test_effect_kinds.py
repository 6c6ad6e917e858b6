"""The effect-kinds table (igserver/effect_kinds.py) is what the scene model, the budget, the effect state,
the profiles and the fire lights read: each kind is accepted, counted, modelled, shaded and lit as its
entry says."""

from __future__ import annotations

import pytest

from igserver.effect_kinds import CONTAINERS, EFFECT_KINDS, EFFECT_TYPES, SHADINGS
from igserver.render.volumes.effects import effect_volumes
from igserver.render.volumes.fire_lights import fire_light
from igserver.render.volumes.profiles import load_profile
from igserver.scene import Scene, apply_patch
from igserver.scene.budget import estimate, volume_count


def _scene(effects) -> Scene:
    return Scene.model_validate({"camera": {"width": 64, "height": 36}, "effects": effects})


def test_the_scene_model_accepts_exactly_the_table():
    schema = Scene.model_json_schema()["$defs"]["Effect"]["properties"]["type"]
    assert schema["enum"] == list(EFFECT_TYPES) == list(EFFECT_KINDS)
    with pytest.raises(ValueError):
        _scene([{"id": "a", "type": "lava"}])


@pytest.mark.parametrize("name", EFFECT_TYPES)
@pytest.mark.parametrize("emits_smoke", [False, True])
def test_each_kind_is_modelled_counted_and_lit_as_its_entry_says(name, emits_smoke):
    kind = EFFECT_KINDS[name]
    assert kind.container in CONTAINERS and kind.shading in SHADINGS
    scene = _scene([{"id": "e", "type": name, "diameter": 2.0, "emits_smoke": emits_smoke}])
    effect = scene.effects[0]
    volumes = effect_volumes(effect, scene)
    # the budget counts what the volumes pass draws
    assert len(volumes) == kind.volume_count(emits_smoke) == volume_count(scene)
    assert volumes[0].kind == name and volumes[0].key == ("e", "fire" if kind.container != "plume" else "smoke")
    if len(volumes) == 2:
        assert volumes[1].kind == kind.plume and volumes[1].key == ("e", "smoke")
    for vol in volumes:
        profile = load_profile(vol.kind, None)
        assert profile.shape[-1] == 4 and profile[..., 3].max() > 0.0
    light = fire_light(effect, scene)
    assert (light is not None) == kind.casts_light


def test_the_budget_weighs_a_fire_with_smoke_twice():
    # the numbers the budget has always given: one volume per effect, two for a fire with its smoke
    effects = [{"id": "f", "type": "fire", "emits_smoke": True}, {"id": "g", "type": "gas_burner", "emits_smoke": True},
               {"id": "s", "type": "smoke", "emits_smoke": True}, {"id": "h", "type": "fire"}]
    scene = _scene(effects)
    assert volume_count(scene) == 5
    cost = estimate(apply_patch(scene, {"quality": {"preset": "medium"}}))
    steps, octaves, resolution, scale = 48, 3, 32, 2
    pixels = 64 * 36
    assert cost.frame == pixels * 80 + 5 * (pixels / scale**2 * steps + 4 * resolution**3 * octaves)


def test_no_code_compares_effect_kinds_by_name():
    # the scene model and the renderer ask the table (a kind's container, shading, plume, light), never
    # ``effect.type == "fire"`` or ``vol.kind in ("fire", "gas_burner")``: a new kind stays one entry
    import ast
    from pathlib import Path

    import igserver

    root = Path(igserver.__file__).resolve().parent
    names = set(EFFECT_TYPES)
    found = []
    for path in [*(root / "scene").rglob("*.py"), *(root / "render").rglob("*.py")]:
        for node in ast.walk(ast.parse(path.read_text())):
            if not isinstance(node, ast.Compare):
                continue
            sides = [node.left, *node.comparators]
            named = any(isinstance(s, ast.Attribute) and s.attr in ("type", "kind") for s in sides)
            consts = [c for s in sides for c in (s.elts if isinstance(s, (ast.Tuple, ast.List, ast.Set)) else [s])
                      if isinstance(c, ast.Constant) and c.value in names]
            if named and consts:
                found.append(f"{path.relative_to(root)}:{node.lineno}")
    assert not found, found
