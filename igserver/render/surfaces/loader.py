"""Loading a glTF 2.0 model (trimesh) into plain arrays the GPU side uploads.

trimesh decodes the accessors (any component type, stride, normalisation), the node hierarchy
(matrix or TRS per node), the metallic-roughness materials and their images. We keep the node
hierarchy rather than flattening it, so that articulated parts (a radar, a door) can be posed by
name each frame. glTF is +Y up with the front toward +Z and -X to the right; entities are x
starboard, y forward, z up, so one fixed rotation ``GLTF_TO_ENTITY`` sits above the root nodes.

Runs in the render process, after ``gltf.check_model`` has bounded the file in the server.
"""

from __future__ import annotations

import io
from dataclasses import dataclass, field

import numpy as np

from ...assets.gltf import check_model, model_path

# x_entity = -x_gltf, y_entity = z_gltf, z_entity = y_gltf (a proper rotation, det = +1).
GLTF_TO_ENTITY = np.array([[-1.0, 0, 0, 0], [0, 0, 1.0, 0], [0, 1.0, 0, 0], [0, 0, 0, 1.0]])

ALPHA_MODES = {"OPAQUE": 0, "MASK": 1, "BLEND": 2}


@dataclass
class MaterialData:
    base_factor: tuple[float, float, float, float] = (1.0, 1.0, 1.0, 1.0)  # linear RGBA
    metallic: float = 1.0
    roughness: float = 1.0
    emissive: tuple[float, float, float] = (0.0, 0.0, 0.0)
    alpha_mode: int = 0
    alpha_cutoff: float = 0.5
    double_sided: bool = False
    # PIL images (RGBA8) or None: base colour and emissive are sRGB, the others linear.
    base_image: object = None
    mr_image: object = None
    normal_image: object = None
    occlusion_image: object = None
    emissive_image: object = None


@dataclass
class PrimitiveData:
    node: int                 # index into ModelData.nodes
    vertices: np.ndarray      # (n, 8) float32: position, normal, uv (glTF node-local frame)
    indices: np.ndarray       # (m,) uint32, triangles
    material: MaterialData


@dataclass
class NodeData:
    name: str
    parent: int               # -1: child of the model root
    local: np.ndarray         # 4x4 float64, parent <- node


@dataclass
class ModelData:
    name: str
    nodes: list[NodeData] = field(default_factory=list)
    primitives: list[PrimitiveData] = field(default_factory=list)
    bounds_center: np.ndarray = field(default_factory=lambda: np.zeros(3))  # entity frame, m
    bounds_radius: float = 1.0

    def node_stack(self, poses: dict[str, np.ndarray] | None = None) -> np.ndarray:
        """``node_matrices`` as one (nodes, 4, 4) array. The rest pose is computed once; a pose
        recomputes only the posed nodes and their descendants (a radar: one node)."""
        rest = self.__dict__.get("_rest_stack")
        if rest is None:
            rest = np.asarray(self.node_matrices()) if self.nodes else np.zeros((0, 4, 4))
            self.__dict__["_rest_stack"] = rest
        if not poses:
            return rest
        out = rest.copy()
        changed = [False] * len(self.nodes)
        for i, node in enumerate(self.nodes):  # parents precede children
            pose = poses.get(node.name)
            if pose is None and not (node.parent >= 0 and changed[node.parent]):
                continue
            local = node.local if pose is None else node.local @ (GLTF_TO_ENTITY.T @ pose @ GLTF_TO_ENTITY)
            out[i] = (out[node.parent] if node.parent >= 0 else GLTF_TO_ENTITY) @ local
            changed[i] = True
        return out

    def node_matrices(self, poses: dict[str, np.ndarray] | None = None) -> list[np.ndarray]:
        """Model-root <- node matrices in the entity frame, with ``poses`` (name -> 4x4 in the
        entity's axes) applied about each posed node's own origin."""
        out: list[np.ndarray] = []
        for node in self.nodes:  # parents precede children
            local = node.local
            if poses and node.name in poses:
                # conjugate the entity-axes pose into the node's glTF-axes frame
                local = local @ (GLTF_TO_ENTITY.T @ poses[node.name] @ GLTF_TO_ENTITY)
            parent = out[node.parent] if node.parent >= 0 else GLTF_TO_ENTITY
            out.append(parent @ local)
        return out


def _rgba(image) -> object:
    if image is None:
        return None
    return image.convert("RGBA")


def _material(visual) -> MaterialData:
    mat = getattr(visual, "material", None)
    out = MaterialData()
    if mat is None:
        return out
    if hasattr(mat, "baseColorFactor") or hasattr(mat, "metallicFactor"):  # PBRMaterial
        if mat.baseColorFactor is not None:
            out.base_factor = tuple(float(c) / 255.0 for c in np.asarray(mat.baseColorFactor).reshape(4))
        out.metallic = 1.0 if mat.metallicFactor is None else float(mat.metallicFactor)
        out.roughness = 1.0 if mat.roughnessFactor is None else float(mat.roughnessFactor)
        if mat.emissiveFactor is not None:
            out.emissive = tuple(float(c) for c in np.asarray(mat.emissiveFactor).reshape(3))
        out.alpha_mode = ALPHA_MODES.get(str(mat.alphaMode or "OPAQUE").upper(), 0)
        out.alpha_cutoff = 0.5 if mat.alphaCutoff is None else float(mat.alphaCutoff)
        out.double_sided = bool(mat.doubleSided)
        out.base_image = _rgba(mat.baseColorTexture)
        out.mr_image = _rgba(mat.metallicRoughnessTexture)
        out.normal_image = _rgba(mat.normalTexture)
        out.occlusion_image = _rgba(mat.occlusionTexture)
        out.emissive_image = _rgba(mat.emissiveTexture)
    else:  # SimpleMaterial (e.g. from OBJ-like sources): diffuse colour and image
        diffuse = getattr(mat, "diffuse", None)
        if diffuse is not None:
            out.base_factor = tuple(float(c) / 255.0 for c in np.asarray(diffuse).reshape(-1)[:4])
        out.base_image = _rgba(getattr(mat, "image", None))
    return out


def _primitive(mesh, node: int) -> PrimitiveData | None:
    faces = np.asarray(getattr(mesh, "faces", ()), dtype=np.int64)
    if faces.ndim != 2 or len(faces) == 0:
        return None  # points and lines are not drawn as surfaces
    positions = np.asarray(mesh.vertices, dtype=np.float64)
    normals = np.asarray(mesh.vertex_normals, dtype=np.float64)
    uv = getattr(mesh.visual, "uv", None)
    uv = np.zeros((len(positions), 2)) if uv is None or len(uv) != len(positions) else np.asarray(uv, float)
    # trimesh flips v on load (OpenGL convention); glTF images have row 0 at v = 0, as we upload them
    uv = np.column_stack([uv[:, 0], 1.0 - uv[:, 1]])
    vertices = np.hstack([positions, normals, uv]).astype(np.float32)
    if not np.all(np.isfinite(vertices)):
        raise ValueError("non-finite vertex data")
    return PrimitiveData(node, vertices, faces.reshape(-1).astype(np.uint32), _material(mesh.visual))


def load_model(name: str) -> ModelData:
    """Load model asset ``name`` (checked first); raises on anything trimesh cannot decode."""
    import trimesh

    check_model(name)
    path = model_path(name)
    with open(path, "rb") as f:
        data = f.read()
    kwargs = {"file_type": path.suffix.lower().lstrip("."), "force": "scene", "process": False}
    if path.suffix.lower() == ".gltf":  # external buffers/images beside the file (checked plain names)
        kwargs["resolver"] = trimesh.resolvers.FilePathResolver(str(path))
    scene = trimesh.load(io.BytesIO(data), **kwargs)
    return model_from_scene(name, scene)


def model_from_scene(name: str, scene) -> ModelData:
    graph = scene.graph
    base = graph.base_frame
    parents = graph.transforms.parents  # child -> parent frame name
    children: dict[str, list[str]] = {}
    for child, parent in parents.items():
        children.setdefault(parent, []).append(child)
    model = ModelData(name)
    index: dict[str, int] = {}
    stack = [(c, -1) for c in sorted(children.get(base, []), reverse=True)]
    while stack:  # depth-first: parents before children
        frame, parent_index = stack.pop()
        if frame in index:
            continue
        parent_frame = parents[frame]
        edge = graph.transforms.edge_data.get((parent_frame, frame), {})
        local = np.asarray(edge.get("matrix", np.eye(4)), dtype=np.float64)
        index[frame] = len(model.nodes)
        model.nodes.append(NodeData(str(frame), parent_index, local))
        geometry = edge.get("geometry")
        if geometry is not None and geometry in scene.geometry:
            prim = _primitive(scene.geometry[geometry], index[frame])
            if prim is not None:
                model.primitives.append(prim)
        stack.extend((c, index[frame]) for c in sorted(children.get(frame, []), reverse=True))
    _bounds(model)
    return model


def _bounds(model: ModelData) -> None:
    matrices = model.node_matrices()
    points = []
    for prim in model.primitives:
        p = prim.vertices[:, :3].astype(np.float64)
        lo, hi = p.min(axis=0), p.max(axis=0)
        corners = np.array([[x, y, z, 1.0] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        points.append((corners @ matrices[prim.node].T)[:, :3])
    if points:
        allp = np.vstack(points)
        lo, hi = allp.min(axis=0), allp.max(axis=0)
        model.bounds_center = 0.5 * (lo + hi)
        model.bounds_radius = max(float(np.linalg.norm(hi - lo)) * 0.5, 1e-3)
