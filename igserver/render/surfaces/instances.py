"""Instances of the entities' models: one row per entity and glTF primitive (the camera-relative
model matrix, column-major, and the material factors), grouped by model into the batches the
surfaces pass draws, with the casters' bounding spheres the shadow maps are fitted to.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...scene.model import Entity
from ..camera import CameraView, body_to_world
from .gpu_models import INSTANCE_FLOATS, GpuModel


@dataclass
class Batch:
    """Instances of one model: rows (instances, primitives, 24) per use, 'view' (in the camera
    frustum) and 'shadow' (casters near the camera), and the casters' bounds (n, 4: centre, radius)."""
    model: GpuModel
    rows: dict[str, np.ndarray] = field(default_factory=dict)
    caster_bounds: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))
    _primitive_rows: dict = field(default_factory=dict)

    def primitive_rows(self, use: str, p: int) -> np.ndarray:
        """Primitive ``p``'s instance rows for ``use``, contiguous float32, made once per batch."""
        key = (use, p)
        if key not in self._primitive_rows:
            self._primitive_rows[key] = np.ascontiguousarray(self.rows[use][:, p, :], dtype=np.float32)
        return self._primitive_rows[key]


def part_poses(entity: Entity) -> dict[str, np.ndarray]:
    poses = {}
    for name, pose in entity.parts.items():
        m = np.eye(4)
        m[:3, :3] = body_to_world(pose.heading, pose.pitch, pose.roll)
        m[:3, 3] = pose.offset
        poses[name] = m
    return poses


def model_instances(entities: list[Entity], model: GpuModel, view: CameraView) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Instance rows (entities, primitives, 24) float32, world bounding-sphere centres (n, 3) and
    radii (n,) of the entities drawing ``model``, all entities of a model at once."""
    data = model.model
    prim_nodes = model.primitive_nodes
    n, p = len(entities), len(prim_nodes)
    scales = np.array([e.scale for e in entities], dtype=np.float64)
    positions = np.array([e.position for e in entities], dtype=np.float64)
    worlds = np.zeros((n, 4, 4))
    worlds[:, 3, 3] = 1.0
    for i, e in enumerate(entities):
        worlds[i, :3, :3] = body_to_world(e.heading, e.pitch, e.roll) * scales[i]  # R @ diag(scale)
    worlds[:, :3, 3] = positions - view.position  # float64 subtraction: camera-relative
    posed = np.array([bool(e.parts) for e in entities])
    nodes = np.broadcast_to(data.node_stack()[prim_nodes], (n, p, 4, 4))
    if posed.any():
        nodes = nodes.copy()
        for i in np.nonzero(posed)[0]:
            nodes[i] = data.node_stack(part_poses(entities[i]))[prim_nodes]
    rows = np.empty((n, p, INSTANCE_FLOATS), np.float32)
    # world @ node per entity and primitive, written column-major (transposed) into 16 floats
    rows[..., :16] = np.einsum("eij,epjk->epki", worlds, nodes).reshape(n, p, 16)
    if data.name == "box":  # the built-in box takes its material from the entity
        rows[..., 16:20] = np.array([(*e.color, e.metallic) for e in entities])[:, None, :]
        rows[..., 20] = np.array([e.roughness for e in entities])[:, None]
    else:
        rows[..., 16:21] = 1.0
    rows[..., 21:] = 0.0
    centres = positions + np.einsum("eij,j->ei", worlds[:, :3, :3], data.bounds_center)
    radii = data.bounds_radius * scales.max(axis=1) * np.where(posed, 1.25, 1.0)
    return rows, centres, radii
