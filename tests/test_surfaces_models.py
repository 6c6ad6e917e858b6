"""glTF models as named assets: the generated demo models, files written by another tool
(trimesh), malformed files and path escapes rejected at the scene model with a clear message,
and a render process that survives a model its loader cannot read."""

from __future__ import annotations

import json
import struct
import zlib

import numpy as np
import pytest
from pydantic import ValidationError

from igserver.assets import gltf
from igserver.render.surfaces.loader import load_model
from igserver.scene.model import Scene

DEMO_MODELS = ("patrol_boat", "pier", "buoy", "crate", "barrel")


@pytest.fixture()
def models_dir(tmp_path, monkeypatch):
    """A configured asset directory (IGSERVER_ASSETS) with an empty models folder."""
    folder = tmp_path / "models"
    folder.mkdir()
    monkeypatch.setenv("IGSERVER_ASSETS", str(tmp_path))
    gltf._cache.clear()
    yield folder
    gltf._cache.clear()


def _entity_scene(model: str, **extra) -> Scene:
    return Scene.model_validate({"entities": [{"id": "e", "model": model, **extra}]})


@pytest.mark.parametrize("name", DEMO_MODELS)
def test_generated_demo_models_check_and_load(name):
    info = gltf.check_model(name)
    model = load_model(name)
    assert model.primitives and info.vertices > 0
    for prim in model.primitives:
        mat = prim.material
        # the generator gives every material all four textures of docs/design.md#surfaces (base, MR, normal, AO)
        assert mat.base_image is not None and mat.mr_image is not None and mat.normal_image is not None
        assert np.all(np.isfinite(prim.vertices))
    if name == "patrol_boat":
        assert {"radar", "gun", "hull", "mast"} <= info.node_names
        # a 36 m boat: the bounding sphere spans its length (radius ~ half the diagonal incl. mast)
        assert 17.0 < model.bounds_radius < 25.0


def _trimesh_scene():
    """A scene written by trimesh (not by our generator): a textured red sphere and a green box
    on a child node 3 m up glTF's +Y (which must come out as the entity's +z)."""
    import trimesh
    from PIL import Image
    from trimesh.visual.material import PBRMaterial

    tex = Image.fromarray(np.full((8, 8, 3), (200, 30, 30), np.uint8))
    sphere = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
    uv = np.zeros((len(sphere.vertices), 2))
    sphere.visual = trimesh.visual.TextureVisuals(uv=uv, material=PBRMaterial(
        baseColorTexture=tex, metallicFactor=0.0, roughnessFactor=0.5))
    box = trimesh.creation.box(extents=(0.5, 0.5, 0.5))
    box.visual = trimesh.visual.TextureVisuals(uv=np.zeros((len(box.vertices), 2)), material=PBRMaterial(
        baseColorFactor=[0.1, 0.8, 0.1, 1.0], metallicFactor=1.0, roughnessFactor=0.3))
    scene = trimesh.Scene()
    scene.add_geometry(sphere, node_name="ball", geom_name="ball")
    up = np.eye(4)
    up[1, 3] = 3.0
    scene.add_geometry(box, node_name="flag", geom_name="flag", transform=up)
    return scene


@pytest.mark.parametrize("suffix", ["glb", "gltf"])
def test_foreign_gltf_loads_with_transforms_and_materials(models_dir, suffix):
    files = _trimesh_scene().export(file_type=suffix)
    if suffix == "glb":
        (models_dir / "foreign.glb").write_bytes(files)
    else:  # .gltf + external .bin buffers beside it
        for fname, data in files.items():
            (models_dir / ("foreign.gltf" if fname.endswith(".gltf") else fname)).write_bytes(data)
    info = gltf.check_model("foreign")
    assert {"ball", "flag"} <= info.node_names
    model = load_model("foreign")
    matrices = model.node_matrices()
    by_name = {n.name: i for i, n in enumerate(model.nodes)}
    # glTF +Y up 3 m -> entity +z 3 m (x, y unchanged at 0)
    np.testing.assert_allclose(matrices[by_name["flag"]][:3, 3], [0.0, 0.0, 3.0], atol=1e-9)
    flag = next(p for p in model.primitives if p.node == by_name["flag"])
    assert flag.material.metallic == pytest.approx(1.0)
    assert flag.material.base_factor[1] == pytest.approx(0.8, abs=1 / 255)  # 8-bit factor storage
    ball = next(p for p in model.primitives if p.node == by_name["ball"])
    assert ball.material.base_image is not None
    radii = np.linalg.norm(ball.vertices[:, :3], axis=1)
    np.testing.assert_allclose(radii, 1.0, atol=1e-5)
    # posing the part by name moves it about its own origin
    pose = np.eye(4)
    pose[:3, 3] = [0.0, 0.0, 1.0]
    np.testing.assert_allclose(model.node_matrices({"flag": pose})[by_name["flag"]][:3, 3], [0, 0, 4.0], atol=1e-9)
    assert _entity_scene("foreign", parts={"flag": {"heading": 30}}).entities[0].parts["flag"].heading == 30


def _png_header(width: int, height: int) -> bytes:
    """A PNG whose header claims width x height (no pixel data needed to read the size)."""
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 6, 0, 0, 0)
    chunk = b"IHDR" + ihdr
    return b"\x89PNG\r\n\x1a\n" + struct.pack(">I", len(ihdr)) + chunk + struct.pack(">I", zlib.crc32(chunk))


def _glb(doc: dict, binary: bytes = b"") -> bytes:
    js = json.dumps(doc).encode()
    js += b" " * (-len(js) % 4)
    binary += b"\0" * (-len(binary) % 4)
    chunks = struct.pack("<II", len(js), 0x4E4F534A) + js
    if binary:
        chunks += struct.pack("<II", len(binary), 0x004E4942) + binary
    return b"glTF" + struct.pack("<II", 2, 12 + len(chunks)) + chunks


def _triangle_doc(count: int = 3, byte_length: int = 36) -> dict:
    return {"asset": {"version": "2.0"}, "buffers": [{"byteLength": byte_length}],
            "bufferViews": [{"buffer": 0, "byteLength": byte_length}],
            "accessors": [{"bufferView": 0, "componentType": 5126, "type": "VEC3", "count": count,
                           "min": [0, 0, 0], "max": [1, 1, 0]}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
            "nodes": [{"mesh": 0, "name": "tri"}], "scenes": [{"nodes": [0]}], "scene": 0}


TRIANGLE = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32).tobytes()


def _bad_files(folder) -> dict[str, str]:
    """name -> words the client-facing message must contain."""
    good = _glb(_triangle_doc(), TRIANGLE)
    (folder / "truncated.glb").write_bytes(good[: len(good) // 2])
    (folder / "version1.glb").write_bytes(good[:4] + struct.pack("<I", 1) + good[8:])
    (folder / "garbage.glb").write_bytes(b"this is not a model at all")
    (folder / "overrun.glb").write_bytes(_glb(_triangle_doc(count=1_000_000), TRIANGLE))
    (folder / "absurd.glb").write_bytes(_glb(_triangle_doc(byte_length=2**40), TRIANGLE))
    doc = _triangle_doc()
    doc["buffers"][0]["uri"] = "missing.bin"
    (folder / "nobuffer.gltf").write_text(json.dumps(doc))
    doc["buffers"][0]["uri"] = "../secret.bin"
    (folder.parent / "secret.bin").write_bytes(TRIANGLE)
    (folder / "escape.gltf").write_text(json.dumps(doc))
    doc = _triangle_doc()
    doc["asset"]["version"] = "1.0"
    (folder / "oldjson.gltf").write_text(json.dumps(doc))
    doc = _triangle_doc()
    png = _png_header(30000, 30000)
    doc["buffers"][0]["byteLength"] = 36 + len(png)
    doc["bufferViews"].append({"buffer": 0, "byteOffset": 36, "byteLength": len(png)})
    doc["images"] = [{"bufferView": 1, "mimeType": "image/png"}]
    (folder / "hugetexture.glb").write_bytes(_glb(doc, TRIANGLE + png))
    return {"truncated": "truncated", "version1": "version 1", "garbage": "magic",
            "overrun": "past the end", "absurd": "byteLength", "nobuffer": "missing",
            "escape": "plain", "oldjson": "version", "hugetexture": "30000x30000"}


def test_malformed_models_are_rejected_with_a_clear_message(models_dir):
    for name, words in _bad_files(models_dir).items():
        with pytest.raises(ValidationError) as err:
            _entity_scene(name)
        text = str(err.value)
        assert words in text, (name, text)
        assert str(models_dir) not in text  # no server paths in client-facing messages


@pytest.mark.parametrize("name", ["../models/crate", "/etc/passwd", "crate/../../x", ".hidden", "a" * 80])
def test_model_names_cannot_escape(name):
    with pytest.raises(ValidationError):
        _entity_scene(name)


def test_unknown_model_and_part_are_rejected():
    with pytest.raises(ValidationError, match="no model asset named"):
        _entity_scene("no_such_model")
    with pytest.raises(ValidationError, match="no part"):
        _entity_scene("patrol_boat", parts={"periscope": {"heading": 10}})
    scene = _entity_scene("patrol_boat", parts={"radar": {"heading": 10}})
    assert scene.entities[0].parts["radar"].heading == 10


def test_check_is_cached_by_file_identity(models_dir):
    path = models_dir / "tri.glb"
    path.write_bytes(_glb(_triangle_doc(), TRIANGLE))
    first = gltf.check_model("tri")
    assert gltf.check_model("tri") is first  # same file: cached answer
    path.write_bytes(_glb(_triangle_doc(count=1_000_000), TRIANGLE))  # replaced on disk: re-checked
    with pytest.raises(gltf.ModelError):
        gltf.check_model("tri")


def test_render_survives_a_model_the_loader_cannot_read(renderer, monkeypatch):
    from helpers import tiny

    from igserver.render.surfaces import gpu_models

    surfaces = renderer.graph.passes["surfaces"]
    camera = {"position": [0, -12, 3], "pitch": -5}
    scene = tiny({"camera": camera, "entities": [{"id": "c", "model": "barrel", "position": [0, 0, 0]}]})
    empty = tiny({"camera": camera})

    def broken(name):
        raise RuntimeError("decoder exploded")

    surfaces.models._models.pop("barrel", None)
    monkeypatch.setattr(gpu_models, "load_model", broken)
    renderer.render(scene)
    with_broken = renderer.read_hdr()
    renderer.render(empty)
    np.testing.assert_array_equal(with_broken, renderer.read_hdr())  # the entity drew nothing
    assert "barrel" in surfaces.models.problems and "RuntimeError" in surfaces.models.problems["barrel"]
    monkeypatch.undo()
    surfaces.models._models.pop("barrel", None)
    renderer.render(scene)
    assert not np.array_equal(renderer.read_hdr(), with_broken)  # loads again once readable
    assert "barrel" not in surfaces.models.problems


def test_committed_demo_models_are_the_generator_output(tmp_path):
    """The repository carries the generator; the shipped .glb files are exactly what it writes."""
    from pathlib import Path

    from igserver.assets import demo_models

    packaged = Path(demo_models.__file__).resolve().parent / "models"
    for name in ("crate", "barrel"):  # the cheap ones; all five use the same deterministic path
        data = demo_models.MODELS[name]().export(file_type="glb")
        assert data == (packaged / f"{name}.glb").read_bytes(), name


def test_blended_surfaces_show_what_lies_behind_them(renderer, models_dir):
    # A glTF material with alphaMode BLEND over the sky and the sea: in the HDR target (linear radiance,
    # before the tone curve) a pane of opacity a must be a * (the same pane opaque) + (1 - a) * (the
    # frame without it). The blended surfaces were drawn in the surfaces pass, before the water and
    # the sky, with a depth mask set on the context (which moderngl ignores: it belongs to the
    # framebuffer): the pane wrote depth, the sky and the sea behind it were never drawn, and it lay
    # over the cleared black. Now they are drawn last of the opaque scene (blended_surfaces pass).
    # Within 2 % of the pane's radiance + 1e-3 (float16 targets, and the blend's own rounding).
    import trimesh
    from trimesh.visual.material import PBRMaterial

    def pane(alpha: float) -> bytes:
        quad = trimesh.Trimesh(vertices=[[-3.0, -3.0, 0.0], [3.0, -3.0, 0.0], [3.0, 3.0, 0.0], [-3.0, 3.0, 0.0]],
                               faces=[[0, 1, 2], [0, 2, 3]], process=False)  # glTF +Y up: upright
        quad.visual = trimesh.visual.TextureVisuals(uv=np.zeros((4, 2)), material=PBRMaterial(
            baseColorFactor=[0.6, 0.2, 0.2, alpha], alphaMode="BLEND", metallicFactor=0.0, roughnessFactor=0.9))
        return trimesh.Scene(quad).export(file_type="glb")

    (models_dir / "pane.glb").write_bytes(pane(0.25))
    (models_dir / "solid.glb").write_bytes(pane(1.0))
    base = {"camera": {"position": [0.0, 0.0, 3.0], "heading": 0.0, "pitch": 0.0, "width": 96, "height": 54,
                       "exposure_ev": 14.0},
            "time": {"utc": "2026-06-21T10:00:00Z"}, "ocean": {"enabled": True},
            "shadows": {"enabled": False}}  # the opaque pane (alpha >= 0.5) would shadow itself, the glass not

    def hdr(entities):
        scene = Scene.model_validate({**base, "entities": entities})
        assert ("blended_surfaces" in renderer.graph.plan(scene)) == bool(entities)
        renderer.render(scene)
        target = renderer.targets_for(96, 54).hdr
        return np.frombuffer(target.read(), dtype=np.float16).reshape(54, 96, 4)[..., :3].astype(np.float64)

    where = {"position": [0.0, 10.0, 3.0]}  # the pane straddles the horizon: sky above, sea below
    glass = hdr([{"id": "p", "model": "pane", **where}])
    solid = hdr([{"id": "p", "model": "solid", **where}])
    bare = hdr([])
    covered = np.abs(solid - bare).max(axis=2) > 0.05 * bare.max()  # the pane's pixels
    assert covered.sum() > 200 and covered[:27].any() and covered[27:].any()
    want = 0.25 * solid + 0.75 * bare
    assert np.abs(glass - want)[covered].max() <= 0.02 * solid[covered].max() + 1e-3


def test_a_replaced_model_file_is_reloaded_within_the_recheck_interval(renderer, models_dir, monkeypatch):
    # The model cache reads a file's identity (a stat) at most once per MODEL_RECHECK_S: a frame
    # within it draws the model it holds, the first after it notices the new file.
    import trimesh

    from igserver.render.surfaces import gpu_models

    clock = [1000.0]
    monkeypatch.setattr(gpu_models.time, "monotonic", lambda: clock[0])
    path = models_dir / "swap.glb"
    path.write_bytes(trimesh.Scene(trimesh.creation.box()).export(file_type="glb"))
    cache = renderer.graph.passes["surfaces"].models
    first = cache.get("swap")
    assert first is not None
    path.write_bytes(trimesh.Scene(trimesh.creation.icosphere(subdivisions=1)).export(file_type="glb"))
    clock[0] += 0.5 * gpu_models.MODEL_RECHECK_S
    assert cache.get("swap") is first
    clock[0] += gpu_models.MODEL_RECHECK_S
    second = cache.get("swap")
    assert second is not first and second.model.primitives[0].indices.size != first.model.primitives[0].indices.size
