"""Hulls keep the sea out: every entity's hull boxes (one per connected piece of the glTF nodes named
``*hull*``, ``*pile*`` or ``*float*``, or the whole built-in box) go to the water shader as inverse box
matrices, and it discards the fragments inside them: a few multiply-adds per hull and fragment, no
extra pass or buffer. Only the LOD blocks near a hull are drawn with that test (``blocks_near_hulls``;
a discard also turns off early depth tests). A box is conservative for a tapered bow (a little sea is
cut beside it, none is drawn inside)."""

from __future__ import annotations

import numpy as np

from ...scene.model import Scene
from ..camera import CameraView, body_to_world

MAX_HULLS = 32  # a pier's piles count one each
_HULL_CACHE: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {}
HULL_PARTS = ("hull", "pile", "float")  # glTF node names (substrings) of the parts that stand or float in the sea


def model_hulls(name: str) -> list[tuple[np.ndarray, np.ndarray]]:
    """(centre, half extent) in the entity frame of a model's hull boxes: one axis-aligned box per
    connected piece of the glTF nodes named ``*hull*``, ``*pile*`` or ``*float*`` (a pier's piles are
    one node but many pieces: the sea shows between them), or the whole built-in box. Other parts
    (decks, superstructure) let the sea show under and around them."""
    if name not in _HULL_CACHE:
        from ..surfaces.loader import load_model
        from ..surfaces.models import BUILTIN, box_model

        try:
            model = box_model() if name in BUILTIN else load_model(name)
        except Exception:  # noqa: BLE001 - a model the surfaces pass cannot draw has no hull either
            _HULL_CACHE[name] = []
            return []
        matrices = model.node_matrices()
        boxes = []
        for prim in model.primitives:
            if name not in BUILTIN and not any(part in model.nodes[prim.node].name.lower() for part in HULL_PARTS):
                continue
            p = np.c_[prim.vertices[:, :3].astype(np.float64), np.ones(len(prim.vertices))] @ matrices[prim.node].T
            p = p[:, :3][np.asarray(prim.indices).reshape(-1)] if prim.indices is not None else p[:, :3]
            for piece in _pieces(p):
                lo, hi = piece.min(axis=0), piece.max(axis=0)
                boxes.append((0.5 * (lo + hi), 0.5 * (hi - lo)))
        _HULL_CACHE[name] = boxes
    return _HULL_CACHE[name]


def _pieces(corners: np.ndarray) -> list[np.ndarray]:
    """The connected pieces of a triangle list (corners (3T, 3)): triangles sharing a vertex position
    (to 0.1 mm) belong to one piece; labels spread by min over each triangle until stable."""
    _, vid = np.unique(np.round(corners / 1e-4).astype(np.int64), axis=0, return_inverse=True)
    tri = vid.reshape(-1, 3)
    label = np.arange(int(vid.max()) + 1 if len(vid) else 0)
    while True:
        low = label[tri].min(axis=1)
        new = label.copy()
        for c in range(3):
            np.minimum.at(new, tri[:, c], low)
        new = new[new]  # follow the chains
        if np.array_equal(new, label):
            break
        label = new
    piece = label[vid]
    return [corners[piece == k] for k in np.unique(piece)]


_HULL_BOXES_MEMO: dict[tuple, list[np.ndarray]] = {}


def hull_boxes(scene: Scene, view: CameraView) -> list[np.ndarray]:
    """Inverse 4x4 matrices (camera-relative world → [-1, 1]³) of the hulls standing or floating in the sea.
    Memoised on exactly what they depend on (each visible entity's model and pose, the camera position,
    the sea level): a still scene pays it once, not per frame."""
    key = (tuple((e.model, tuple(e.position), e.heading, e.pitch, e.roll, tuple(e.scale))
                 for e in scene.entities if e.visible), tuple(float(x) for x in view.position), scene.ocean.level)
    if key not in _HULL_BOXES_MEMO:
        if len(_HULL_BOXES_MEMO) >= 8:
            _HULL_BOXES_MEMO.clear()
        _HULL_BOXES_MEMO[key] = _hull_boxes(scene, view)
    return list(_HULL_BOXES_MEMO[key])


def _hull_boxes(scene: Scene, view: CameraView) -> list[np.ndarray]:
    boxes = []
    for entity in scene.entities:
        if not entity.visible:
            continue
        rot = body_to_world(entity.heading, entity.pitch, entity.roll)
        scale = np.asarray(entity.scale)
        for centre, half in model_hulls(entity.model):
            m = np.eye(4)
            m[:3, :3] = rot @ np.diag(scale * half)
            m[:3, 3] = view.relative(entity.position) + rot @ (scale * centre)
            lowest = m[2, 3] - np.sum(np.abs(m[2, :3]))
            if lowest + view.position[2] > scene.ocean.level + 30.0:  # well above any sea: not in it
                continue
            boxes.append((float(np.linalg.norm(m[:3, 3])), np.linalg.inv(m)))
    # The nearest first: beyond MAX_HULLS the farthest go (they cover the fewest pixels).
    return [inv for _, inv in sorted(boxes, key=lambda b: b[0])[:MAX_HULLS]]


def blocks_near_hulls(nodes: np.ndarray, hulls: list[np.ndarray], margin: float) -> np.ndarray:
    """Which LOD blocks (rows of camera-relative x0, y0, side, level) come within ``margin`` (m) of a
    hull box's horizontal footprint: only those need the fragment hull test. All hulls at once: a
    box's footprint is its centre ± the sum of |column| of its matrix (the extreme corners)."""
    if not hulls or not len(nodes):
        return np.zeros(len(nodes), dtype=bool)
    m = np.linalg.inv(np.asarray(hulls))  # (H, 4, 4) box → camera-relative
    reach = np.sum(np.abs(m[:, :2, :3]), axis=2)  # (H, 2)
    lo, hi = m[:, :2, 3] - reach - margin, m[:, :2, 3] + reach + margin
    x0, y0, side = (nodes[:, c, None].astype(np.float64) for c in range(3))
    return np.any((x0 <= hi[None, :, 0]) & (x0 + side >= lo[None, :, 0]) & (y0 <= hi[None, :, 1])
                  & (y0 + side >= lo[None, :, 1]), axis=1)
