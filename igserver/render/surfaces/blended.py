"""The blended surfaces pass: glTF materials with alphaMode BLEND drawn after the water and the sky.

The surfaces pass prepares their program and instances; this pass runs their draw at its place in
the frame, and is needed only when a visible entity's model has a BLEND material.
"""

from __future__ import annotations

from ...assets.gltf import check_model
from ...scene.model import Scene
from ..camera import CameraView
from ..passes import RenderPass
from .gpu_models import model_identity


_BLENDS: dict[str, tuple[tuple, bool]] = {}  # name -> (file identity, has a BLEND material)


def _model_blends(name: str) -> bool:
    """Whether the model has a BLEND material, from its check, kept while its file's identity
    (model_identity, read once a second) stays the same."""
    try:
        identity = model_identity(name)
        held = _BLENDS.get(name)
        if held is not None and held[0] == identity:
            return held[1]
        blends = check_model(name).blended
    except Exception:  # a model that cannot be read draws nothing (the surfaces pass reports it)
        return False
    if len(_BLENDS) > 256:
        _BLENDS.clear()
    _BLENDS[name] = (identity, blends)
    return blends


class BlendedSurfacesPass(RenderPass):
    """Surfaces of glTF materials with alphaMode BLEND (glass, windows, canopies), drawn after the
    water and the sky so what lies behind them shows through them; the surfaces pass prepared their
    program and instances this frame (frame.resources["blended_surfaces"])."""

    name = "blended_surfaces"

    def needed(self, scene: Scene, view: CameraView) -> bool:
        return any(e.visible and _model_blends(e.model) for e in scene.entities)

    def execute(self, frame, targets) -> None:
        draw = frame.resources.get("blended_surfaces")
        if draw is not None:
            draw()
