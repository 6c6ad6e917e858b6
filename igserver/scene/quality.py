"""Quality: the preset of every pipeline's knobs and the frame-time or frame-rate target the IG holds."""

from __future__ import annotations

from typing import Annotated, Literal, get_args

from pydantic import AfterValidator, Field

from .base import Strict


def _target_fps(v: float) -> float:
    if v != 0.0 and not 5.0 <= v <= 240.0:  # NaN fails both
        raise ValueError("target_fps is 0 (off) or 5-240 frames/s")
    return v


# A frame rate the overload controller holds (render/overload.py): 0 = off, else 5-240 frames/s. Below 5
# a frame is no longer a picture in motion; above 240 no display shows it.
TargetFps = Annotated[float, AfterValidator(_target_fps)]


PresetName = Literal["low", "medium", "high", "auto"]
PRESET_NAMES: tuple[str, ...] = get_args(PresetName)  # the command lines' choices


class Quality(Strict):
    """Quality presets (igserver/render/presets.py): every pipeline's knobs per level, chosen from the
    error-vs-time curves of ``igserver quality``."""

    preset: PresetName = Field(
        "medium", description="knob set of every pipeline; auto = the overload controller chooses the knobs and the "
        "render scale per frame (render/overload.py) to hold target_fps (or, when that is 0, target_ms)")
    target_ms: float = Field(
        40.0, ge=1.0, le=10_000.0, description="ms, frame-time target (render + readback) of the auto preset")
    target_fps: TargetFps = Field(
        0.0, description="frames/s the IG holds by trading detail for time (render scale 1.0-0.5 and, with the "
        "auto preset, every pipeline's knobs; a fixed preset keeps its knobs); 0 = off, else 5-240")
