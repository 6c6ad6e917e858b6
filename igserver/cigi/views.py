"""CIGI views -> the scene's channels (docs/cigi.md#views-and-channels).

View 0 is the eyepoint: its View Control places and turns the camera, its View Definition sets the
camera's frustum (mapping.py). Every other view a host defines (View Control or View Definition with
view id N > 0) is a channel of the same eyepoint, with channel id ``str(N)``:

- attitude: the view's orientation relative to view 0's, ``R0^T RN`` (both View Control attitudes
  relative to their entity, ``render.camera.body_to_world``), as the channel's heading/pitch/roll
  offsets from the camera (in (-180, 180]);
- frustum: the View Definition half-angles, ``fov_left = -left``, ``fov_right = right``,
  ``fov_up = top``, ``fov_down = -bottom`` (a view whose frustum does not contain its axis is refused
  with the datagram, as any out-of-range value); near/far when their enables are set;
- size: the channel's own when the scene has a channel of that id already (an operator sized it over
  REST), else the camera's width and height.

Once any view N > 0 exists, view 0 is channel ``"0"`` too (no attitude offset, the camera's frustum), so
the channels are every view of the host in view-id order. The views' own eyepoint offsets (x, y, z) are
not used: channels share the eyepoint (a non-zero one is counted in ``igserver_cigi_skipped_total``).
Channels with other ids (an operator's) are left as they are.
"""

from __future__ import annotations

import math

import numpy as np

from ..render.camera import body_to_world
from .geo import angles
from .packets_host import ViewControl, ViewDefinition
from .session import ViewSpec

DEFAULT_FRUSTUM = {"left": -30.0, "right": 30.0, "top": 20.0, "bottom": -20.0}  # the packet's defaults


def channel_id(view_id: int) -> str:
    return str(view_id)


def view_control(work, p: ViewControl) -> None:
    """View Control for a view N > 0: its attitude offsets (enables honoured)."""
    work.entity(p.entity_id, "View Control")
    view = work.session.views.get(p.view_id) or ViewSpec()
    yaw, pitch, roll = view.attitude
    attitude = (p.yaw if p.yaw_enable else yaw, p.pitch if p.pitch_enable else pitch,
                p.roll if p.roll_enable else roll)
    if any(getattr(p, k) and getattr(p, f"{k}_enable") for k in ("x", "y", "z")):
        work.plan.skipped["view_eyepoint_offset"] += 1  # channels share the eyepoint
    work.session.views[p.view_id] = ViewSpec(attitude, view.frustum, view.near, view.far)
    work.views_changed = True


def view_definition(work, p: ViewDefinition) -> None:
    """View Definition for a view N > 0: its frustum half-angles and clip distances (enables honoured)."""
    view = work.session.views.get(p.view_id) or ViewSpec()
    frustum = dict(view.frustum or DEFAULT_FRUSTUM)
    for name in ("left", "right", "top", "bottom"):
        if getattr(p, f"{name}_enable"):
            frustum[name] = getattr(p, name)
    if p.projection != 0:
        work.plan.skipped["orthographic_view"] += 1
    work.session.views[p.view_id] = ViewSpec(view.attitude, frustum, p.near if p.near_enable else view.near,
                                             p.far if p.far_enable else view.far)
    work.views_changed = True


def _offsets(view0_attitude: tuple[float, float, float], attitude: tuple[float, float, float]) -> dict[str, float]:
    """heading/pitch/roll of a view relative to view 0 (deg, in (-180, 180])."""
    relative = body_to_world(*view0_attitude).T @ body_to_world(*attitude)
    heading, pitch, roll = angles(np.asarray(relative))
    # into (-180, 180], rounded to 1e-9 deg (float32 packets: a yaw of 60 reads 60, not 59.99999999999999)
    wrap = lambda a: round(float(a - 360.0 * math.ceil((a - 180.0) / 360.0)), 9) + 0.0  # noqa: E731
    return {"heading": wrap(heading), "pitch": round(float(pitch), 9) + 0.0, "roll": wrap(roll)}


def _half_angles(frustum: dict) -> dict[str, float]:
    return {"fov_left": -frustum["left"], "fov_right": frustum["right"], "fov_up": frustum["top"],
            "fov_down": -frustum["bottom"]}


def place_views(work) -> None:
    """The channels of the host's views into the patch (after the packets; only when a view changed)."""
    session = work.session
    if not session.views:
        return
    camera = {**work.tree["camera"], **work.patch.get("camera", {})}
    view0 = session.view.attitude if session.view is not None else (0.0, 0.0, 0.0)
    channels = list(work.patch.get("channels", work.tree.get("channels", [])))
    index = {c["id"]: i for i, c in enumerate(channels)}
    frustum0 = camera.get("frustum") or _symmetric(camera)
    wanted = {channel_id(0): {"heading": 0.0, "pitch": 0.0, "roll": 0.0, **_half_angles(frustum0)}}
    for number in sorted(session.views):
        view = session.views[number]
        entry = {**_offsets(view0, view.attitude), **_half_angles(view.frustum or frustum0)}
        entry.update({k: v for k, v in (("near", view.near), ("far", view.far)) if v is not None})
        wanted[channel_id(number)] = entry
    for cid, entry in wanted.items():
        if cid in index:
            channels[index[cid]] = {**channels[index[cid]], **entry}
        else:
            index[cid] = len(channels)
            channels.append({"id": cid, "width": camera["width"], "height": camera["height"], **entry})
    work.patch["channels"] = channels


def _symmetric(camera: dict) -> dict:
    """The signed half-angles of a camera without a frustum: fov_y and the frame's aspect (square pixels)."""
    half_y = math.radians(camera["fov_y"]) / 2
    half_x = math.degrees(math.atan(math.tan(half_y) * camera["width"] / camera["height"]))
    return {"left": -half_x, "right": half_x, "top": math.degrees(half_y), "bottom": -math.degrees(half_y)}


def drop_views(work) -> None:
    """IG Control reset: the channels of the host's views leave the scene (an operator's stay)."""
    session = work.session
    if not session.views:
        return
    ours = {channel_id(0), *(channel_id(n) for n in session.views)}
    work.patch["channels"] = [c for c in work.patch.get("channels", work.tree.get("channels", []))
                              if c["id"] not in ours]
    session.views.clear()
