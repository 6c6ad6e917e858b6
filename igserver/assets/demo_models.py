"""Generator of the demo's glTF models, with procedural PBR textures (reproducible: fixed seeds).

    python -m igserver.assets.demo_models [--out DIR]     (default: igserver/assets/models)

Writes ``patrol_boat.glb`` (a 36 m patrol boat: lofted hull with flare and sheer, deckhouse,
bridge with a window band, mast, a turning radar on the glTF node ``radar``, a bow gun mount
on the node ``gun``), ``pier.glb`` (a 60 m concrete pier on piles with timber fenders and
bollards), ``buoy.glb`` (a red can buoy with a light), ``crate.glb`` and ``barrel.glb``.
Models are built in the entity frame (x starboard, y forward, z up, metres; the waterline at
z = 0 for floating things) and converted to glTF's +Y-up axes on export. Textures are tileable
value noise shaped into paint, rust, concrete, timber and steel, stored as JPEG.
"""

from __future__ import annotations

import argparse
import io
import math
from pathlib import Path

import numpy as np
from PIL import Image

TEX = 128  # px a side: enough for metre-scale tiling at simulator viewing distances, small files
# entity axes -> glTF axes (the inverse of loader.GLTF_TO_ENTITY, which is orthogonal)
ENTITY_TO_GLTF = np.array([[-1.0, 0, 0, 0], [0, 0, 1.0, 0], [0, 1.0, 0, 0], [0, 0, 0, 1.0]]).T


# --- procedural textures ---------------------------------------------------------------------
def value_noise(rng: np.random.Generator, cells: int, size: int = TEX) -> np.ndarray:
    """Smooth tileable noise in [0,1]: a random grid, wrapped 3x3, bicubic-upsampled, centre crop."""
    grid = rng.random((cells, cells)).astype(np.float32)
    tiled = np.tile(grid, (3, 3))
    img = Image.fromarray(tiled, mode="F").resize((3 * size, 3 * size), Image.BICUBIC)
    out = np.asarray(img)[size:2 * size, size:2 * size]
    return np.clip((out - out.min()) / max(float(np.ptp(out)), 1e-6), 0.0, 1.0)


def fbm(rng: np.random.Generator, octaves: int = 4, base_cells: int = 4) -> np.ndarray:
    total, weight, norm = np.zeros((TEX, TEX), np.float32), 1.0, 0.0
    for i in range(octaves):
        total += weight * value_noise(rng, base_cells * 2**i)
        norm += weight
        weight *= 0.5
    return total / norm


def _jpeg(rgb: np.ndarray) -> Image.Image:
    """RGB float [0,1] -> a PIL image whose format is JPEG (trimesh then stores it as JPEG)."""
    buf = io.BytesIO()
    Image.fromarray((np.clip(rgb, 0, 1) * 255 + 0.5).astype(np.uint8), "RGB").save(buf, "JPEG", quality=88)
    buf.seek(0)
    return Image.open(buf)


def srgb_encode(linear: np.ndarray) -> np.ndarray:
    linear = np.clip(linear, 0.0, 1.0)
    return np.where(linear <= 0.0031308, 12.92 * linear, 1.055 * np.power(linear, 1 / 2.4) - 0.055)


def normal_from_height(height: np.ndarray, strength: float) -> np.ndarray:
    """Tangent-space normal map (glTF: +x right, +y up in the image) from a tileable height field."""
    dx = (np.roll(height, -1, axis=1) - np.roll(height, 1, axis=1)) * 0.5
    dy = (np.roll(height, 1, axis=0) - np.roll(height, -1, axis=0)) * 0.5
    n = np.stack([-dx * strength, -dy * strength, np.ones_like(height)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return n * 0.5 + 0.5


def material(name: str, seed: int, kind: str, color, metallic: float = 0.0, roughness: float = 0.6,
             emissive=None, seams: float = 1.0):
    """A trimesh PBRMaterial with base colour, metallic-roughness, normal and occlusion textures."""
    from trimesh.visual.material import PBRMaterial

    rng = np.random.default_rng(seed)
    color = np.asarray(color, np.float32)
    n1, n2 = fbm(rng), fbm(rng, 3, 8)
    y = np.linspace(0.0, 1.0, TEX, endpoint=False)[:, None] * np.ones((1, TEX))
    x = y.T
    if kind == "paint":  # painted steel: faint mottling, rust streaks running down, plate seams
        rust = np.clip((n2 - 0.72) * 5.0, 0, 1) * np.clip(0.4 + 0.6 * value_noise(rng, 16), 0, 1)
        base = color * (0.9 + 0.2 * n1[..., None])
        base = base * (1 - rust[..., None]) + np.array([0.18, 0.07, 0.03]) * rust[..., None]
        rough = roughness + 0.15 * (n1 - 0.5) + 0.35 * rust
        metal = metallic * (1 - rust)
        # welded plate seams: one horizontal and one vertical per texture repeat
        seam = np.exp(-((y % 1.0 - 0.5) ** 2) / 0.0004) + np.exp(-((x % 1.0 - 0.5) ** 2) / 0.0004)
        height = 0.3 * n2 - 0.6 * seams * np.clip(seam, 0, 1)
        strength = 4.0
    elif kind == "metal":  # bare or galvanised steel: brushed streaks
        streak = value_noise(rng, 64)[:, :1] * np.ones((1, TEX))
        base = color * (0.85 + 0.3 * (0.6 * n1 + 0.4 * streak))[..., None]
        rough = roughness + 0.2 * (streak - 0.5) + 0.1 * (n2 - 0.5)
        metal = np.full_like(n1, metallic)
        height, strength = 0.5 * streak + 0.2 * n2, 2.0
    elif kind == "concrete":
        pores = (value_noise(rng, 48) > 0.8).astype(np.float32)
        base = color * (0.75 + 0.4 * n1 - 0.2 * pores)[..., None]
        rough = roughness + 0.1 * (n2 - 0.5)
        metal = np.zeros_like(n1)
        height, strength = 0.6 * n2 - 0.4 * pores, 5.0
    elif kind == "timber":  # planks along x with grain and dark gaps
        plank = (y * 4) % 1.0
        gap = (plank < 0.05).astype(np.float32)
        grain = value_noise(rng, 4)[:1, :] * np.ones((TEX, 1))
        grain = 0.5 + 0.5 * np.sin(40 * y + 8 * value_noise(rng, 8) + 6 * grain)
        base = color * (0.7 + 0.25 * grain + 0.2 * n1 - 0.6 * gap)[..., None]
        rough = roughness + 0.1 * (grain - 0.5) + 0.2 * gap
        metal = np.zeros_like(n1)
        height, strength = 0.2 * grain - 1.0 * gap, 4.0
    elif kind == "glass":
        base = color * (0.9 + 0.1 * n1)[..., None]
        rough = np.full_like(n1, roughness)
        metal = np.zeros_like(n1)
        height, strength = np.zeros_like(n1), 0.0
    else:
        raise ValueError(kind)
    base_img = _jpeg(srgb_encode(np.clip(base, 0, 1)))
    occlusion = np.clip(1.0 - 0.5 * np.clip(-height, 0, 1), 0, 1)
    # glTF metallic-roughness texture: G = roughness, B = metallic (R unused; we keep occlusion there)
    mr = np.stack([occlusion, np.clip(rough, 0.03, 1.0), np.clip(metal, 0.0, 1.0)], axis=-1)
    mr_img = _jpeg(mr)
    normal_img = _jpeg(normal_from_height(height, strength))
    kwargs = dict(name=name, baseColorTexture=base_img, metallicRoughnessTexture=mr_img,
                  normalTexture=normal_img, occlusionTexture=mr_img, metallicFactor=1.0, roughnessFactor=1.0)
    if emissive is not None:  # a uniformly lit panel (lit windows, a lamp): factor only
        kwargs["emissiveFactor"] = list(emissive)
    return PBRMaterial(**kwargs)


# --- geometry -----------------------------------------------------------------------------------
def textured(mesh, mat, tile: float = 2.0, smooth: bool = False):
    """A copy of ``mesh`` with one vertex per face corner, box-projected UVs (``tile`` m per texture
    repeat) and ``mat``; ``smooth`` keeps the mesh's smooth vertex normals (cylinders)."""
    import trimesh

    faces = np.asarray(mesh.faces)
    verts = np.asarray(mesh.vertices)[faces].reshape(-1, 3)
    face_n = np.repeat(np.asarray(mesh.face_normals), 3, axis=0)
    normals = np.asarray(mesh.vertex_normals)[faces].reshape(-1, 3) if smooth else face_n
    axis = np.argmax(np.abs(face_n), axis=1)
    u = np.where(axis == 0, verts[:, 1], verts[:, 0])
    v = np.where(axis == 2, verts[:, 1], verts[:, 2])
    uv = np.column_stack([u, v]) / tile
    out = trimesh.Trimesh(verts, np.arange(len(verts)).reshape(-1, 3), vertex_normals=normals, process=False,
                          visual=trimesh.visual.TextureVisuals(uv=uv, material=mat))
    return out


def box(extents, center, mat, tile=2.0):
    import trimesh

    m = trimesh.creation.box(extents=extents)
    m.apply_translation(center)
    return textured(m, mat, tile)


def cylinder(radius, z0, z1, center_xy, mat, sections=20, tile=1.0):
    import trimesh

    m = trimesh.creation.cylinder(radius=radius, height=z1 - z0, sections=sections)
    m.apply_translation([center_xy[0], center_xy[1], 0.5 * (z0 + z1)])
    return textured(m, mat, tile, smooth=True)


def hull_mesh(length: float, beam: float, keel: float, deck: float, bow_sheer: float, mat):
    """Lofted hull: stations along y with a round-bilge section that narrows and rises to the bow."""
    import trimesh

    stations = 28
    ring = 11  # points per half section, keel to deck edge
    ys = np.linspace(-0.5, 0.5, stations) * length
    sections = []
    for y in ys:
        t = (y / length) + 0.5  # 0 stern .. 1 bow
        half = 0.5 * beam * (1.0 - max(t - 0.55, 0.0) ** 1.6 / 0.45 ** 1.6 * 0.97) * (0.92 + 0.08 * min(t * 6, 1))
        top = deck + bow_sheer * t ** 2.2
        bottom = keel * (1.0 - 0.55 * max(t - 0.7, 0) / 0.3) * (0.75 + 0.25 * min(t * 4, 1))
        pts = []
        for k in range(ring):  # angle from keel (k=0) round the bilge up to the deck edge
            a = k / (ring - 1)
            x = half * math.sin(a * math.pi / 2) ** 0.6 * (1.0 + 0.06 * a)  # flare near the deck
            z = bottom + (top - bottom) * (1 - math.cos(a * math.pi / 2)) ** 0.9
            pts.append((x, y, z))
        sections.append(pts)
    verts, faces = [], []
    for side in (1.0, -1.0):
        base = len(verts)
        for pts in sections:
            verts += [(side * x, y, z) for x, y, z in pts]
        for i in range(stations - 1):
            for k in range(ring - 1):
                a, b = base + i * ring + k, base + (i + 1) * ring + k
                quad = (a, b, b + 1, a + 1) if side > 0 else (a, a + 1, b + 1, b)
                faces += [(quad[0], quad[1], quad[2]), (quad[0], quad[2], quad[3])]
    # transom (stern plate) and deck
    base = len(verts)
    stern = sections[0]
    verts += [(x, stern[0][1], z) for x, _, z in stern] + [(-x, stern[0][1], z) for x, _, z in stern]
    for k in range(ring - 1):
        faces += [(base + k, base + k + 1, base + ring + k + 1), (base + k, base + ring + k + 1, base + ring + k)]
    mesh = trimesh.Trimesh(np.asarray(verts), np.asarray(faces), process=True)
    mesh.fix_normals()
    return textured(mesh, mat, tile=3.0, smooth=True)


def deck_mesh(length: float, beam: float, deck: float, bow_sheer: float, mat):
    """The deck surface following the hull's sheer and plan shape (a strip of quads)."""
    import trimesh

    stations = 28
    ys = np.linspace(-0.5, 0.5, stations) * length
    verts, faces = [], []
    for y in ys:
        t = (y / length) + 0.5
        half = 0.5 * beam * (1.0 - max(t - 0.55, 0.0) ** 1.6 / 0.45 ** 1.6 * 0.97) * (0.92 + 0.08 * min(t * 6, 1))
        half *= 1.05
        z = deck + bow_sheer * t ** 2.2 - 0.05
        verts += [(-half, y, z), (half, y, z)]
    for i in range(stations - 1):
        a = 2 * i
        faces += [(a, a + 1, a + 3), (a, a + 3, a + 2)]
    return textured(trimesh.Trimesh(np.asarray(verts), np.asarray(faces), process=False), mat, tile=2.0)


# --- models -------------------------------------------------------------------------------------
def _scene(parts: list[tuple[str, object, np.ndarray | None]]):
    """trimesh Scene from (node name, mesh in entity axes, node translation or None) converted to glTF axes."""
    import trimesh

    scene = trimesh.Scene()
    for name, mesh, pivot in parts:
        mesh = mesh.copy()
        mesh.apply_transform(ENTITY_TO_GLTF)
        transform = np.eye(4)
        if pivot is not None:
            t = np.eye(4)
            t[:3, 3] = pivot
            transform = ENTITY_TO_GLTF @ t @ ENTITY_TO_GLTF.T
        scene.add_geometry(mesh, node_name=name, geom_name=name, transform=transform)
    return scene


def patrol_boat():
    hull_paint = material("hull_paint", 11, "paint", (0.16, 0.19, 0.22), metallic=0.0, roughness=0.45)
    boot = material("boot_topping", 12, "paint", (0.05, 0.05, 0.05), roughness=0.6)
    deck = material("deck", 13, "paint", (0.09, 0.10, 0.10), roughness=0.85, seams=0.5)
    house = material("superstructure", 14, "paint", (0.55, 0.57, 0.58), roughness=0.4, seams=0.3)
    glass = material("bridge_windows", 15, "glass", (0.02, 0.025, 0.03), roughness=0.08,
                     emissive=(0.35, 0.3, 0.2))
    steel = material("mast_steel", 16, "metal", (0.56, 0.57, 0.58), metallic=1.0, roughness=0.35)
    dark = material("radar_dark", 17, "paint", (0.06, 0.06, 0.07), roughness=0.5)
    L, B, keel, D, sheer = 36.0, 7.2, -1.8, 2.2, 1.0
    parts = [
        ("hull", hull_mesh(L, B, keel, D, sheer, hull_paint), None),
        ("boot_topping", box((B * 0.98, L * 0.8, 0.35), (0, -2.5, 0.0), boot, 2.0), None),
        ("deck", deck_mesh(L, B, D, sheer, deck), None),
        ("deckhouse", box((5.6, 12.0, 2.6), (0, 1.0, D + 1.3 + 0.15), house), None),
        ("bridge", box((5.0, 6.0, 2.2), (0, 3.5, D + 2.6 + 1.1 + 0.15), house), None),
        ("bridge_windows", box((5.08, 0.4, 0.9), (0, 6.35, D + 2.6 + 1.45 + 0.15), glass, 1.0), None),
        ("bridge_windows_side", box((5.1, 4.0, 0.8), (0, 4.0, D + 2.6 + 1.5 + 0.15), glass, 1.0), None),
        ("funnel", box((1.8, 2.4, 2.0), (0, -3.4, D + 2.6 + 1.0 + 0.15), house), None),
        ("mast", cylinder(0.18, D + 4.9, D + 11.0, (0, 3.0), steel), None),
        ("yard", box((3.6, 0.16, 0.16), (0, 3.0, D + 9.6), steel, 1.0), None),
        ("aft_deck_box", box((3.0, 3.0, 1.0), (0, -12.0, D + 0.55), steel, 1.0), None),
    ]
    # articulated: the radar turns about its pedestal on the mast platform (node origin = pivot)
    import trimesh

    radar = trimesh.util.concatenate([
        cylinder(0.25, 0.0, 0.45, (0, 0), dark),
        box((3.6, 0.25, 0.35), (0, 0, 0.62), dark, 1.0),
    ])
    parts.append(("radar", radar, np.array([0.0, 3.0, D + 11.0])))
    gun = trimesh.util.concatenate([
        cylinder(0.8, 0.0, 0.9, (0, 0), house),
        box((0.25, 2.6, 0.25), (0, 1.6, 0.55), steel, 1.0),
    ])
    parts.append(("gun", gun, np.array([0.0, 12.5, D + 0.45])))
    return _scene(parts)


def pier():
    concrete = material("pier_concrete", 21, "concrete", (0.42, 0.41, 0.38), roughness=0.85)
    wet = material("pile_concrete", 22, "concrete", (0.22, 0.22, 0.21), roughness=0.6)
    timber = material("fender_timber", 23, "timber", (0.30, 0.20, 0.12), roughness=0.75)
    iron = material("bollard_iron", 24, "metal", (0.08, 0.08, 0.08), metallic=0.8, roughness=0.55)
    L, W, top = 60.0, 8.0, 2.0
    parts = [("deck", box((W, L, 0.6), (0, 0, top - 0.3), concrete, 3.0), None)]
    piles = []
    for y in np.arange(-L / 2 + 3, L / 2, 6.0):
        for x in (-W / 2 + 0.6, W / 2 - 0.6):
            piles.append(cylinder(0.35, -6.0, top - 0.6, (x, y), wet, 12))
    import trimesh

    parts.append(("piles", trimesh.util.concatenate(piles), None))
    fenders = [box((0.3, L, 0.5), (s * (W / 2 + 0.15), 0, top - 0.5), timber, 2.0) for s in (-1, 1)]
    parts.append(("fenders", trimesh.util.concatenate(fenders), None))
    bollards = [cylinder(0.2, top, top + 0.6, (s * (W / 2 - 0.5), y), iron, 10)
                for y in np.arange(-L / 2 + 5, L / 2, 10.0) for s in (-1, 1)]
    parts.append(("bollards", trimesh.util.concatenate(bollards), None))
    return _scene(parts)


def buoy():
    import trimesh

    red = material("buoy_red", 31, "paint", (0.45, 0.03, 0.02), roughness=0.4)
    steel = material("buoy_steel", 32, "metal", (0.4, 0.4, 0.42), metallic=1.0, roughness=0.4)
    lamp = material("buoy_lamp", 33, "glass", (0.2, 0.25, 0.1), roughness=0.1, emissive=(0.6, 0.9, 0.4))
    cone = trimesh.creation.cone(radius=0.9, height=1.0, sections=20)
    cone.apply_translation([0, 0, 1.2])
    parts = [
        ("float", cylinder(0.9, -0.6, 1.2, (0, 0), red, 20), None),
        ("top", textured(cone, red, 1.0), None),
        ("tower", cylinder(0.08, 2.0, 3.0, (0, 0), steel, 8), None),
        ("lamp", cylinder(0.15, 3.0, 3.35, (0, 0), lamp, 12), None),
    ]
    return _scene(parts)


def crate():
    wood = material("crate_wood", 41, "timber", (0.45, 0.33, 0.2), roughness=0.8)
    return _scene([("crate", box((1.2, 1.2, 1.2), (0, 0, 0.6), wood, 1.2), None)])


def barrel():
    blue = material("barrel_paint", 51, "paint", (0.05, 0.12, 0.35), metallic=0.0, roughness=0.35)
    return _scene([("barrel", cylinder(0.3, 0.0, 0.9, (0, 0), blue, 20, 0.9), None)])


MODELS = {"patrol_boat": patrol_boat, "pier": pier, "buoy": buoy, "crate": crate, "barrel": barrel}


def write_models(out: Path) -> dict[str, int]:
    out.mkdir(parents=True, exist_ok=True)
    sizes = {}
    for name, build in MODELS.items():
        data = build().export(file_type="glb")
        (out / f"{name}.glb").write_bytes(data)
        sizes[name] = len(data)
    return sizes


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parent / "models")
    args = parser.parse_args(argv)
    for name, size in write_models(args.out).items():
        print(f"{args.out / name}.glb  {size / 1024:.0f} KiB")


if __name__ == "__main__":
    main()
