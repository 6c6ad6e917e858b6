"""Small helpers shared by the tests (importable as ``helpers``: pytest puts tests/ on sys.path)."""

from __future__ import annotations

import numpy as np

from igserver.scene import Scene, apply_patch


def tiny(patch: dict | None = None, width: int = 64, height: int = 36) -> Scene:
    base = Scene.model_validate({"camera": {"width": width, "height": height}})
    return apply_patch(base, patch or {})


def luminance(rgba: np.ndarray) -> np.ndarray:
    rgb = rgba[..., :3].astype(np.float64)
    return 0.2126 * rgb[..., 0] + 0.7152 * rgb[..., 1] + 0.0722 * rgb[..., 2]
