"""The foam and surf rows of ``igserver quality water``: what the sea's white water measures against
published field data, next to the water pass's cost.

* **Whitecaps** (``foam_fraction``, ``whitecap_rows``): the fraction of the sea covered by foam, per
  pixel in the linear HDR target (before the tone map, whose curve would weigh thin foam up) between
  the frame without whitecaps (foam threshold -1), the drawn frame and the frame all white (threshold
  10): (drawn - bare) / (white - bare) in luminance, over the sea, summed over four headings. The
  reference is Monahan & O'Muircheartaigh (1980), W = 3.84e-6 U10^3.41 (``whitecap_coverage``); the
  row's error is the ratio measured / W, from a bridge 15 m up looking at the horizon and from 300 m.
* **Swash** (``beach_frame``, ``swash_row``): on a slope beach, six frames over one peak period from
  a camera on the sand looking along the shore. A pixel of sand is reached by the swash when its
  luminance moves by over 5 % of its median over the period; the highest sand reached per image column
  (the run-up line) is compared with Stockdon et al. (2006)'s R2 (``shore.runup_r2``), and the wet sand
  below the reach (0.2-0.7 R2) with the dry sand above 1.3 R2 (beach photographs: wet sand reflects
  about 0.6 of dry sand's light).
"""

from __future__ import annotations

import statistics

import numpy as np

WHITECAP_VIEWS = {"bridge": (15.0, -3.0), "300 m": (300.0, -20.0)}  # camera height m, pitch deg
HEADINGS = (0.0, 90.0, 180.0, 270.0)  # deg from north; the wind blows from 250°
SHORE_VIEW = {"position": [395.0, -120.0, 4.0], "heading": 30.0, "pitch": -12.0, "exposure_ev": 14.5}
SWASH_FRAMES = 6
FAR_M = 150.0  # pixels past this distance are left out of the beach (a few pixels a metre)


def foam_scene(wind: float, height: float, pitch: float, heading: float = 30.0, t: float = 100.0,
               size=(240, 135)):
    """The open sea at ``wind`` (m/s, from 250°) on a June morning, seen from ``height`` m."""
    from ..scene import Scene, apply_patch

    return apply_patch(Scene(), {
        "camera": {"position": [0.0, 0.0, height], "heading": heading, "pitch": pitch, "fov_y": 55.0,
                   "width": size[0], "height": size[1], "exposure_ev": 13.0},
        "time": {"utc": "2026-06-21T10:00:00Z", "sim_time": t}, "location": {"lat": 43.0, "lon": 5.0},
        "weather": {"wind_speed": wind, "wind_direction": 250.0}, "ocean": {"enabled": True}})


def hdr_luminance(renderer, scene) -> np.ndarray:
    """The frame's linear luminance (cd/m² scaled as the HDR target holds it), float64 per pixel."""
    from ..photometry import LUMA

    renderer.render(scene)
    return renderer.read_hdr()[..., :3].astype(np.float64) @ np.asarray(LUMA, dtype=np.float64)


def foam_fraction(renderer, scene) -> tuple[np.ndarray, np.ndarray]:
    """Per pixel foam fraction in [0, 1] and the sea mask (where the all-white frame differs from bare)."""
    water = renderer.graph.passes["water"]
    frames = {}
    try:
        for name, threshold in (("drawn", None), ("bare", -1.0), ("white", 10.0)):
            water.foam_threshold = threshold
            frames[name] = hdr_luminance(renderer, scene)
    finally:
        water.foam_threshold = None
    span = frames["white"] - frames["bare"]
    sea = span > 0.05 * np.median(span[span > 0])
    return np.clip((frames["drawn"] - frames["bare"]) / np.where(sea, span, 1.0), 0.0, 1.0), sea


def whitecap_coverage_seen(renderer, wind: float, height: float, pitch: float, size=(240, 135)) -> float:
    """The foam-covered fraction of the sea over the four headings (``HEADINGS``)."""
    covered, area = 0.0, 0
    for heading in HEADINGS:
        c, sea = foam_fraction(renderer, foam_scene(wind, height, pitch, heading, size=size))
        covered += float(c[sea].sum())
        area += int(sea.sum())
    return covered / max(area, 1)


def _water_ms(renderer, scene, frames: int) -> float:
    from ..scene import apply_patch

    t0 = scene.time.sim_time
    times = [renderer.render(apply_patch(scene, {"time": {"sim_time": t0 + i / 30.0}}), timed=True).pass_ms["water"]
             for i in range(frames + 1)]
    return statistics.median(times[1:]) if frames else float("nan")


def whitecap_rows(renderer, winds: list[float], size: tuple[int, int], frames: int) -> list[dict]:
    """Per wind and view (``WHITECAP_VIEWS``): coverage, Monahan & O'Muircheartaigh's W, their ratio,
    and the water pass's median ms at ``size``."""
    from ..water.surface import whitecap_coverage

    rows = []
    for wind in winds:
        want = whitecap_coverage(wind)
        for view, (height, pitch) in WHITECAP_VIEWS.items():
            got = whitecap_coverage_seen(renderer, wind, height, pitch)
            ms = _water_ms(renderer, foam_scene(wind, height, pitch, size=size), frames)
            rows.append({"part": "whitecaps", "view": f"{view}, wind {wind:g} m/s", "measured": got,
                         "reference": want, "ratio": got / want, "ms": ms})
            print(f"whitecaps {view} {wind:g} m/s: {100 * got:.2f} % of the sea against {100 * want:.2f} % "
                  f"(x{got / want:.2f}), water {ms:.1f} ms", flush=True)
    return rows


def beach_frame(renderer, scene) -> tuple[np.ndarray, np.ndarray]:
    """(linear luminance, world xy per pixel: NaN for the sky and past ``FAR_M``) of the frame, each
    pixel's world point from the distance target along its view ray."""
    from ..render.camera import make_view

    lum = hdr_luminance(renderer, scene)
    world = make_view(scene.camera).pixel_world(renderer.read_distance(), FAR_M)
    return lum, world[..., :2]


def dominant_waves_of(scene) -> tuple[float, float]:
    """(H0 m, Tp s): the deep-water height and peak period that set the scene's run-up."""
    from ..render.water.shore import dominant_waves
    from ..water import sea_surface

    h0, tp, _ = dominant_waves(scene, sea_surface(scene.ocean, scene.weather))
    return h0, tp


def swash_frames(renderer, scene) -> tuple[np.ndarray, np.ndarray, float]:
    """``SWASH_FRAMES`` luminance frames over one peak period, the world xy of the first, and Stockdon's
    R2 (m) for the scene's slope and waves."""
    from ..render.water.shore import runup_r2
    from ..scene import apply_patch

    h0, tp = dominant_waves_of(scene)
    t0 = scene.time.sim_time
    out = [beach_frame(renderer, apply_patch(scene, {"time": {"sim_time": t0 + k * tp / SWASH_FRAMES}}))
           for k in range(SWASH_FRAMES)]
    return np.stack([lum for lum, _ in out]), out[0][1], runup_r2(h0, tp, scene.ocean.bathymetry.slope)


def swash_reach(lum: np.ndarray, elevation: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per pixel: did the swash move it (luminance off its median by over 5 %); per image column with
    enough sand: the highest sand elevation (m) the swash reached."""
    median = np.median(lum, axis=0)
    changed = np.max(np.abs(lum - median), axis=0) > 0.05 * median
    reach = []
    for col in range(lum.shape[2]):
        on_land = (elevation[:, col] > 0.03) & np.isfinite(elevation[:, col])
        hit = on_land & changed[:, col]
        if on_land.sum() > 10 and hit.any():
            reach.append(float(elevation[hit, col].max()))
    return changed, np.asarray(reach)


def swash_row(renderer, size: tuple[int, int], frames: int) -> list[dict]:
    """The run-up line against Stockdon's R2 and wet/dry sand on ``sea_beach`` from the shore."""
    from ..scene import apply_patch
    from ..scene.files import load_scene
    from ..water.bathymetry import depth_at

    scene = apply_patch(load_scene("sea_beach"), {"camera": {**SHORE_VIEW, "width": 240, "height": 135},
                                                  "time": {"sim_time": 100.0}})
    lum, xy, r2 = swash_frames(renderer, scene)
    elevation = -depth_at(scene.ocean.bathymetry, xy)
    _, reach = swash_reach(lum, elevation)
    median = np.median(lum, axis=0)
    wet = median[(elevation > 0.2 * r2) & (elevation < 0.7 * r2)]
    dry = median[(elevation > 1.3 * r2) & (elevation < 3.0 * r2)]
    ms = _water_ms(renderer, apply_patch(scene, {"camera": {"width": size[0], "height": size[1]}}), frames)
    run_up = float(reach.mean()) if len(reach) else float("nan")
    wet_dry = float(np.median(wet) / np.median(dry)) if wet.size and dry.size else float("nan")
    print(f"swash: run-up {run_up:.2f} m against R2 {r2:.2f} m (x{run_up / r2:.2f}); wet/dry sand {wet_dry:.2f} "
          f"against 0.6; water {ms:.1f} ms", flush=True)
    return [{"part": "swash run-up", "view": "sea_beach from the sand", "measured": run_up, "reference": r2,
             "ratio": run_up / r2, "ms": ms},
            {"part": "wet / dry sand", "view": "sea_beach from the sand", "measured": wet_dry, "reference": 0.6,
             "ratio": wet_dry / 0.6, "ms": ms}]


def markdown(rows: list[dict]) -> list[str]:
    """The foam and surf table of the water report."""
    lines = ["", "Foam and surf against field data (whitecaps: Monahan & O'Muircheartaigh 1980, per cent of the "
             "sea over four headings; swash: Stockdon et al. 2006 R2, m; wet/dry sand luminance against 0.6):", "",
             "| part | view | measured | reference | ratio | water ms |", "|---|---|---|---|---|---|"]
    for r in rows:
        scale, unit = (100.0, " %") if r["part"] == "whitecaps" else (1.0, " m" if "run-up" in r["part"] else "")
        lines.append(f"| {r['part']} | {r['view']} | {scale * r['measured']:.2f}{unit} | "
                     f"{scale * r['reference']:.2f}{unit} | {r['ratio']:.2f} | {r['ms']:.1f} |")
    return lines
