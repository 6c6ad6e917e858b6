"""Built-in models as lists of boxes (local frame: x starboard, y forward, z up; unit size).

Each part: (centre, half-extent, colour multiplier) in units of the entity's scale.
"""

from __future__ import annotations

import numpy as np

Part = tuple[tuple[float, float, float], tuple[float, float, float], float]

MODELS: dict[str, list[Part]] = {
    "box": [((0.0, 0.0, 0.5), (0.5, 0.5, 0.5), 1.0)],
    # A ship: hull, bow taper block, superstructure, funnel (scale = beam, length, hull height).
    "ship": [
        ((0.0, -0.05, 0.5), (0.5, 0.42, 0.5), 1.0),
        ((0.0, 0.42, 0.55), (0.32, 0.08, 0.45), 1.0),
        ((0.0, -0.25, 1.3), (0.38, 0.12, 0.3), 1.6),
        ((0.0, -0.28, 1.9), (0.1, 0.04, 0.3), 0.4),
    ],
    # A pier: deck on piles.
    "pier": [
        ((0.0, 0.0, 0.9), (0.5, 0.5, 0.1), 1.0),
        ((-0.4, -0.4, 0.4), (0.04, 0.02, 0.5), 0.6),
        ((0.4, -0.4, 0.4), (0.04, 0.02, 0.5), 0.6),
        ((-0.4, 0.4, 0.4), (0.04, 0.02, 0.5), 0.6),
        ((0.4, 0.4, 0.4), (0.04, 0.02, 0.5), 0.6),
        ((-0.4, 0.0, 0.4), (0.04, 0.02, 0.5), 0.6),
        ((0.4, 0.0, 0.4), (0.04, 0.02, 0.5), 0.6),
    ],
}


def unit_cube() -> np.ndarray:
    """36 vertices of a cube [-1,1]^3: interleaved position(3), normal(3), float32."""
    faces = []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            n = np.zeros(3)
            n[axis] = sign
            u, v = np.roll(np.eye(3), 1, axis=0)[axis], np.roll(np.eye(3), 2, axis=0)[axis]
            if sign < 0:
                u, v = v, u
            corners = [n + a * u + b * v for a, b in ((-1, -1), (1, -1), (1, 1), (-1, -1), (1, 1), (-1, 1))]
            faces += [np.concatenate([c, n]) for c in corners]
    return np.asarray(faces, dtype=np.float32)
