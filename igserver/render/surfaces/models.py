"""The built-in model: ``box``, a 1 m cube standing on z = 0 (entity frame: x starboard, y
forward, z up), drawn through the same path as glTF models. Its material comes from the
entity's ``color``/``metallic``/``roughness`` (per-instance factors on a white material)."""

from __future__ import annotations

import numpy as np

from .loader import GLTF_TO_ENTITY, MaterialData, ModelData, NodeData, PrimitiveData, _bounds

BUILTIN = ("box",)


def unit_cube() -> np.ndarray:
    """36 vertices of a cube [-1,1]^3: interleaved position(3), normal(3), float32; every triangle
    counter-clockwise seen from outside (glTF's front faces)."""
    faces = []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            n = np.zeros(3)
            n[axis] = sign
            u, v = np.roll(np.eye(3), 1, axis=0)[axis], np.roll(np.eye(3), 2, axis=0)[axis]
            # Counter-clockwise seen from outside: the triangles' edges (2u, 2u + 2v) have
            # u x v = n. Wound the other way, every face the camera sees is a back face, and the
            # shader (double-sided: a back face turns its normal toward the eye) lit the inside.
            if sign > 0:
                u, v = v, u
            corners = [n + a * u + b * v for a, b in ((-1, -1), (1, -1), (1, 1), (-1, -1), (1, 1), (-1, 1))]
            faces += [np.concatenate([c, n]) for c in corners]
    return np.asarray(faces, dtype=np.float32)


def box_model() -> ModelData:
    cube = unit_cube().astype(np.float64)
    to_gltf = GLTF_TO_ENTITY[:3, :3].T  # the loader maps glTF axes to entity axes above the roots
    positions = (cube[:, :3] * 0.5 + [0.0, 0.0, 0.5]) @ to_gltf.T
    normals = cube[:, 3:] @ to_gltf.T
    vertices = np.hstack([positions, normals, np.zeros((len(cube), 2))]).astype(np.float32)
    model = ModelData("box", [NodeData("box", -1, np.eye(4))],
                      [PrimitiveData(0, vertices, np.arange(len(cube), dtype=np.uint32), MaterialData())])
    _bounds(model)
    return model
