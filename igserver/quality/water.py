"""``igserver quality water``: error of the sea against run time (docs/design.md#quality).

Two errors per setting, next to the water pass's median ms and the triangles drawn:

* Surface (cm): the GPU-displaced mesh (the water vertex shader run by transform feedback on every
  block of the frame, float32, with its LOD fade and morph) against the float64 evaluation of the
  full wave set at the same rest points (igserver.water). RMS and max over the blocks within 200 m
  (what a ship's bridge sees up close) and over all blocks (``far`` columns: where the LOD fades
  waves that are smaller than the mesh spacing; their slopes go to the shading instead).
* Picture (8-bit sRGB): the frame against a high-LOD, many-wave reference (64 waves, LOD error
  0.25 px, 512² detail maps): per-pixel RMSE over the sea, and the RMSE after a 9x9 box blur
  (``lowpass``: brightness and colour of the sea, what survives a different random realisation).
  The LOD and detail knobs are compared with a 24-wave reference (the same sea, pixel for pixel);
  wave counts with the 64-wave one: a different realisation of the same spectrum, so their per-pixel
  RMSE is large by construction and the lowpass error and the statistics are the fair measure.
* Atmosphere: the shipped water shades with per-frame tables of the sky reflection and the aerial
  perspective (render/water/sea_tables.glsl); the references evaluate the same atmosphere functions
  per pixel and per vertex instead, so every row's picture error includes the tables' error, and the
  ``atmosphere`` row (exact vs tables at the defaults) shows it alone with both costs.
* Under water: the ``underwater`` row is the same sea at the defaults seen from 3 m below the surface
  looking 30° up, against the same view at the reference settings (the error over the whole frame).
* Statistics: Hs (4σ of the mesh surface) and mean-square slope of mesh + detail against the targets
  (WMO Hs; Cox–Munk slope variance).

Knobs: ocean.wave_count, ocean.lod_error, ocean.detail_resolution (one at a time from the default), the
mesh's ring rule (``mesh coarse``: the ``low`` preset's), the finest vertex spacing (``spacing``: the
shortest mesh wave over ``lod.SPACING_PER_WAVE``, rounded to a power of two; the reference uses 16) and
the atmosphere (tables or exact).

Usage: igserver quality water [--out out/quality_water.md] [--size 640x360] [--frames 3]
       [--waves 8,16,24,32,48] [--lod 0.5,1,2,4] [--detail 64,128,256] [--spacing 16,8,4,2] [--wind 9.4]
       [--camera 0,0,12] [--pitch -6] [--whitecap-winds 9.4,22.6] [--no-swash]   (an empty list skips that knob)

Foam and surf (water_surf.py): whitecap coverage from a bridge and from 300 m against Monahan &
O'Muircheartaigh (1980), and on ``sea_beach`` the swash's run-up against Stockdon et al. (2006)'s R2 and
wet against dry sand, each with the water pass's ms.
"""

from __future__ import annotations

import argparse
import json
import statistics
from pathlib import Path

import numpy as np

from . import water_surf
from .volumes import box_blur  # the same 9x9 lowpass as the volumes study

REFERENCE = {"wave_count": 64, "lod_error": 0.25, "detail_resolution": 512}
REFERENCE_SPACING_PER_WAVE = 16.0  # the reference mesh's finest spacing: 1/16 of the shortest mesh wave
DEFAULTS = {"wave_count": 24, "lod_error": 1.0, "detail_resolution": 128}
LOWPASS_LIMIT = 3.0  # 8-bit levels
SURFACE_LIMIT_CM = 1.0  # near-field max error: the host-query bound of the issue
UNDERWATER_DEPTH = 3.0  # m below the mean level: the ``underwater`` row's eye
UNDERWATER_PITCH = 30.0  # deg up: Snell's window and the surface beyond it in the frame


def study_scene(width: int, height: int, wind: float, settings: dict, position=(0.0, 0.0, 12.0), pitch: float = -6.0):
    from ..scene import Scene

    return Scene.model_validate({
        "camera": {"position": list(position), "heading": 200.0, "pitch": pitch, "fov_y": 55.0,
                   "width": width, "height": height},
        "time": {"utc": "2026-06-21T10:00:00Z", "sim_time": 100.0}, "location": {"lat": 43.0, "lon": 5.0},
        "weather": {"wind_speed": wind, "wind_direction": 250.0},
        "ocean": {"enabled": True, **settings},
    })


def surface_errors(renderer, scene, mesh: str = "default") -> dict:
    from ..water import sea_surface

    selection, pos = renderer.graph.passes["water"].capture(scene, mesh)
    sea = sea_surface(scene.ocean, scene.weather)
    cam = np.asarray(scene.camera.position)
    flat = pos.reshape(-1, 3).astype(np.float64)
    out = {}
    for label, radius in (("near", 200.0), ("far", np.inf)):
        # The host query at each vertex's displaced x, y (its Newton inverse finds the rest point, so
        # morphed vertices are compared where they really are).
        verts = flat[np.sum(flat[:, :2] ** 2, axis=1) < radius**2]
        if len(verts) == 0:
            out[label] = (float("nan"), float("nan"))
            continue
        world = verts[:, :2] + cam[:2]
        r2 = np.sum(verts[:, :2] ** 2, axis=1)
        mesh_z = verts[:, 2] + cam[2] + r2 / (2.0 * 6.371e6) - scene.ocean.level
        q = sea.query(world, scene.time.sim_time)["height"]
        err = (mesh_z - q) * 100.0
        out[label] = (float(np.sqrt(np.mean(err**2))), float(np.max(np.abs(err))))
    out["triangles"] = selection.triangles
    return out


def statistics_of(scene) -> tuple[float, float]:
    from ..water import sea_surface
    from ..water.spectrum import mean_square_slope

    sea = sea_surface(scene.ocean, scene.weather)
    xy = np.random.default_rng(5).uniform(-2000.0, 2000.0, (6000, 2))
    hs = 4.0 * float(np.std(sea.evaluate(xy, 37.0)["position"][:, 2]))
    return hs, mean_square_slope(sea.waves) + mean_square_slope(sea.detail)


def parse_args(argv: list[str]) -> argparse.Namespace:
    ap = argparse.ArgumentParser(prog="igserver quality water")
    ap.add_argument("--out", default="out/quality_water.md")
    ap.add_argument("--size", default="640x360")
    ap.add_argument("--frames", type=int, default=3)
    ap.add_argument("--waves", default="8,16,24,32,48")
    ap.add_argument("--lod", default="0.5,1,2,4")
    ap.add_argument("--detail", default="64,128,256")
    ap.add_argument("--spacing", default="8,4,2", help="SPACING_PER_WAVE values (8 is the default)")
    ap.add_argument("--presets", default="low,medium,high", help="quality presets, each as the renderer runs it")
    ap.add_argument("--wind", type=float, default=9.4)
    ap.add_argument("--camera", default="0,0,12", help="camera position x,y,z (m)")
    ap.add_argument("--pitch", type=float, default=-6.0)
    ap.add_argument("--whitecap-winds", default="9.4,22.6",
                    help="winds (m/s) of the whitecap rows (water_surf.py); empty: none")
    ap.add_argument("--no-swash", action="store_true", help="leave out the swash rows (sea_beach)")
    return ap.parse_args(argv)


def run(argv: list[str]) -> int:
    args = parse_args(argv)
    result = measure(args)
    write_markdown(args, result)
    return 0


def study(quick: bool = False):
    """The sea's curves for the combined report (igserver/quality/report.py): the picture's RMSE over
    the sea against the same 24 waves at high LOD, detail and spacing, per knob, and the presets as the
    renderer runs them. Wave counts are left out: a count is a different sea (another realisation),
    not a cheaper picture of the same one (``igserver quality water`` shows them with the statistics)."""
    from .report import Point, Study

    argv = ["--waves", "", "--frames", "5", "--whitecap-winds", "", "--no-swash"]  # error against ms only  # timed frames a point (a median of fewer swings with the machine)
    if quick:
        argv += ["--lod", "1,4", "--detail", "64,128", "--spacing", "8,4"]
    result = measure(parse_args(argv))
    points = []
    for r in result["rows"]:
        if r["knob"] == "preset":
            setting = f"{r['value']}: {result['preset_knobs'][r['value']]}"
            points.append(Point("preset", setting, r["rmse"], r["ms"], r["value"], _extra(r)))
        else:
            points.append(Point(r["knob"], f"{r['knob']}={r['value']}", r["rmse"], r["ms"], None, _extra(r)))
    notes = [f"Wind 9.4 m/s, camera 12 m, pitch -6°, 640x360. Error against the same 24 waves at high LOD "
             f"and detail ({result['reference_ms']:.0f} ms: LOD error 0.25 px, 512² detail maps, finest "
             "spacing 1/16, the atmosphere per pixel).",
             "Surface errors (cm, against the float64 wave set) and Hs are in `igserver quality water`'s table."]
    return Study("water", "RMSE over the sea, 8-bit sRGB", "ms, water pass at 640x360 (median)", points,
                 notes, result["renderer"])


def _extra(row: dict) -> dict:
    return {"lowpass": row["lowpass"], "triangles": row["triangles"], "near max cm": row["near_max_cm"]}


def measure(args: argparse.Namespace) -> dict:
    """Every row of the study (one knob varied at a time, then each preset) and its references."""
    from ..render import presets
    from ..render.renderer import Renderer

    position = tuple(float(v) for v in args.camera.split(","))
    width, height = (int(v) for v in args.size.split("x"))
    renderer = Renderer()

    water = renderer.graph.passes["water"]
    from ..render.water import lod

    DEFAULT_SPACING = lod.SPACING_PER_WAVE

    def render(settings: dict, exact: bool = False, mesh: str = "default", spacing: float = DEFAULT_SPACING,
               knobs=None):
        from ..render.water.water import WaterKnobs

        water.exact_atmosphere = exact
        # the scene's own values, or a preset's knobs as the renderer applies them
        water.settings = knobs or WaterKnobs(detail_scale=1.0, lod_error_scale=1.0, mesh=mesh)
        lod.SPACING_PER_WAVE = spacing
        scene = study_scene(width, height, args.wind, settings, position, args.pitch)
        times = []
        for i in range(args.frames + 1):
            from ..scene import apply_patch

            s = apply_patch(scene, {"time": {"sim_time": 100.0 + i / 30.0}})
            result = renderer.render(s, timed=True)
            if i:
                times.append(result.pass_ms["water"])
        final = renderer.render(scene)  # the picture at sim_time 100
        water.exact_atmosphere, water.settings = False, None
        lod.SPACING_PER_WAVE = DEFAULT_SPACING
        return scene, final.rgba[..., :3].astype(np.float64), statistics.median(times)

    _, ref_many, ref_ms = render(REFERENCE, exact=True, spacing=REFERENCE_SPACING_PER_WAVE)
    # LOD and detail knobs are compared with the same 24 waves at high LOD and detail (the same sea,
    # pixel for pixel); wave counts with the 64-wave reference (another realisation: lowpass, stats).
    _, ref_same, _ = render({**REFERENCE, "wave_count": DEFAULTS["wave_count"]}, exact=True,
                            spacing=REFERENCE_SPACING_PER_WAVE)
    lod.SPACING_PER_WAVE = DEFAULT_SPACING
    sky_only = renderer.render(study_scene(width, height, args.wind, {**DEFAULTS, "enabled": False}, position,
                                           args.pitch)).rgba[..., :3]
    sea_mask = np.any(np.abs(ref_same - sky_only) > 2, axis=-1)
    rows = []
    def values(text: str, kind):
        return [kind(v) for v in text.split(",") if v.strip()]

    preset_knobs = {level: presets.knobs("water", level) for level in values(args.presets, str)}
    variants = ([("wave_count", v) for v in values(args.waves, int)]
                + [("lod_error", v) for v in values(args.lod, float)]
                + [("detail_resolution", v) for v in values(args.detail, int)]
                + [("spacing", v) for v in values(args.spacing, float)]
                + [("mesh", "coarse"), ("atmosphere", "exact"), ("atmosphere", "tables")]
                + [("preset", level) for level in preset_knobs])
    for knob, value in variants:
        settings = {**DEFAULTS, knob: value} if knob not in ("atmosphere", "mesh", "spacing", "preset") else dict(DEFAULTS)
        knobs = preset_knobs.get(value) if knob == "preset" else None
        mesh = value if knob == "mesh" else knobs.mesh if knobs else "default"
        scene, img, ms = render(settings, exact=value == "exact", mesh=mesh,
                                spacing=value if knob == "spacing" else DEFAULT_SPACING, knobs=knobs)
        finest = water.stats.get("finest_spacing_m")
        ref_img = ref_many if knob == "wave_count" else ref_same
        rmse = float(np.sqrt(np.mean((img - ref_img)[sea_mask] ** 2)))
        low = float(np.sqrt(np.mean((box_blur(img) - box_blur(ref_img))[sea_mask] ** 2)))
        lod.SPACING_PER_WAVE = value if knob == "spacing" else DEFAULT_SPACING
        surf = surface_errors(renderer, scene, mesh)
        lod.SPACING_PER_WAVE = DEFAULT_SPACING
        hs, mss = statistics_of(scene)
        row = {"knob": knob, "value": value, **settings, "ms": ms, "triangles": surf["triangles"],
               "finest_spacing_m": finest,
               "rmse": rmse, "lowpass": low, "near_rms_cm": surf["near"][0], "near_max_cm": surf["near"][1],
               "far_rms_cm": surf["far"][0], "far_max_cm": surf["far"][1], "hs": hs, "mss": mss}
        rows.append(row)
        print(f"{knob} {value}: {ms:6.1f} ms {surf['triangles']:7d} tri  finest {finest} m  rmse {rmse:5.1f} lowpass {low:4.1f}  "
              f"near {surf['near'][0]:.3f}/{surf['near'][1]:.3f} cm  far {surf['far'][0]:.1f}/{surf['far'][1]:.1f} cm"
              f"  Hs {hs:.2f} m  mss {mss:.4f}", flush=True)
    rows.append(underwater_row(renderer, args, (width, height), position))
    surf = water_surf.whitecap_rows(renderer, values(args.whitecap_winds, float), (width, height), args.frames)
    if not args.no_swash:
        surf += water_surf.swash_row(renderer, (width, height), args.frames)
    result = {"rows": rows, "surf": surf, "reference_ms": ref_ms, "renderer": renderer.caps.renderer, "size": (width, height),
              "position": position, "default_spacing": DEFAULT_SPACING,
              "preset_knobs": {level: _knobs_text(k) for level, k in preset_knobs.items()}}
    renderer.release()
    return result


def underwater_row(renderer, args: argparse.Namespace, size: tuple[int, int], position) -> dict:
    """The ``underwater`` row: the same sea at the defaults seen from UNDERWATER_DEPTH m below the surface
    looking UNDERWATER_PITCH deg up (Snell's window, the water column: render/water/underwater.glsl),
    its water-pass ms, and its picture error over the whole frame against the same view at the
    reference's LOD, detail, spacing and exact atmosphere (24 waves: the same sea)."""
    from ..render.water import lod
    from ..scene import apply_patch

    water = renderer.graph.passes["water"]
    eye = (position[0], position[1], -UNDERWATER_DEPTH)
    default_spacing = lod.SPACING_PER_WAVE

    def picture(settings: dict, exact: bool, spacing: float, frames: int):
        water.exact_atmosphere, lod.SPACING_PER_WAVE = exact, spacing
        scene = study_scene(size[0], size[1], args.wind, settings, eye, UNDERWATER_PITCH)
        times = [renderer.render(apply_patch(scene, {"time": {"sim_time": 100.0 + i / 30.0}}), timed=True)
                 .pass_ms["water"] for i in range(frames + 1)][1:]
        img = renderer.render(scene).rgba[..., :3].astype(np.float64)
        water.exact_atmosphere, lod.SPACING_PER_WAVE = False, default_spacing
        return scene, img, statistics.median(times) if times else float("nan")

    _, ref, _ = picture({**REFERENCE, "wave_count": DEFAULTS["wave_count"]}, True, REFERENCE_SPACING_PER_WAVE, 0)
    scene, img, ms = picture(dict(DEFAULTS), False, default_spacing, args.frames)
    assert water.stats.get("underwater"), "the study's eye is not under water"
    surf = surface_errors(renderer, scene)
    hs, mss = statistics_of(scene)
    rmse = float(np.sqrt(np.mean((img - ref) ** 2)))
    low = float(np.sqrt(np.mean((box_blur(img) - box_blur(ref)) ** 2)))
    print(f"underwater: {ms:6.1f} ms rmse {rmse:5.1f} lowpass {low:4.1f}", flush=True)
    return {"knob": "underwater", "value": f"{UNDERWATER_DEPTH:g} m down, pitch {UNDERWATER_PITCH:g}", **DEFAULTS,
            "ms": ms, "triangles": surf["triangles"], "finest_spacing_m": water.stats.get("finest_spacing_m"),
            "rmse": rmse, "lowpass": low, "near_rms_cm": surf["near"][0], "near_max_cm": surf["near"][1],
            "far_rms_cm": surf["far"][0], "far_max_cm": surf["far"][1], "hs": hs, "mss": mss}


def _knobs_text(knobs) -> str:
    return f"detail ×{knobs.detail_scale:g}, LOD error ×{knobs.lod_error_scale:g}, mesh {knobs.mesh}"


def write_markdown(args: argparse.Namespace, result: dict) -> None:
    from ..water.spectrum import beaufort_hs, cox_munk_mss

    rows, (width, height), position = result["rows"], result["size"], result["position"]
    ref_ms, default_spacing = result["reference_ms"], result["default_spacing"]
    good = [r for r in rows if r["lowpass"] <= LOWPASS_LIMIT and r["near_max_cm"] <= SURFACE_LIMIT_CM]
    good = [r for r in good if r["knob"] != "underwater"]  # another view: not a setting to choose
    choice = min(good, key=lambda r: r["ms"]) if good else min(rows, key=lambda r: r["lowpass"])
    target_hs, target_mss = beaufort_hs(args.wind), cox_munk_mss(args.wind)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    lines = [
        f"# Water quality ({width}x{height}, wind {args.wind} m/s, renderer {result['renderer']})",
        "",
        f"Camera {list(position)}, pitch {args.pitch}. Reference: {REFERENCE}, finest spacing 1/"
        f"{REFERENCE_SPACING_PER_WAVE:g} of the shortest mesh wave ({ref_ms:.1f} ms). Targets: Hs {target_hs:.2f} m (WMO), "
        f"mean-square slope {target_mss:.4f} (Cox–Munk).",
        "Surface: GPU mesh vs float64 wave set at the same points, cm (near: within 200 m; far: all blocks).",
        "Picture: 8-bit sRGB over the sea; lowpass = after a 9x9 box blur.",
        "Presets: " + "; ".join(f"{level} = {text}" for level, text in result["preset_knobs"].items()) + ".",
        "",
        "| knob | value | water ms | triangles | rmse | lowpass | near rms/max cm | far rms/max cm | Hs m | mss |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        mark = (" **(default)**" if all(r[k] == DEFAULTS[k] for k in DEFAULTS) and r["value"] not in ("exact", "coarse")
                and r["knob"] != "preset" and (r["knob"] != "spacing" or r["value"] == default_spacing) else "")
        mark = "" if r["knob"] == "underwater" else mark
        value = f"{r['value']:g} ({r['finest_spacing_m']:g} m)" if r["knob"] == "spacing" else r["value"]
        lines.append(f"| {r['knob']} | {value}{mark} | {r['ms']:.1f} | {r['triangles']} | {r['rmse']:.1f} | "
                     f"{r['lowpass']:.1f} | {r['near_rms_cm']:.3f} / {r['near_max_cm']:.3f} | "
                     f"{r['far_rms_cm']:.1f} / {r['far_max_cm']:.1f} | {r['hs']:.2f} | {r['mss']:.4f} |")
    if good:
        lines += ["", f"Cheapest with lowpass <= {LOWPASS_LIMIT} and near max <= {SURFACE_LIMIT_CM} cm: "
                  f"{choice['knob']} = {choice['value']} ({choice['ms']:.1f} ms)."]
    else:
        lines += ["", f"No setting meets lowpass <= {LOWPASS_LIMIT} and near max <= {SURFACE_LIMIT_CM} cm; "
                  f"lowest lowpass: {choice['knob']} = {choice['value']}."]
    if result.get("surf"):
        lines += water_surf.markdown(result["surf"])
    out.write_text("\n".join(lines) + "\n")
    out.with_suffix(".json").write_text(json.dumps({"reference": REFERENCE, "rows": rows, "choice": choice,
                                                    "surf": result.get("surf", [])}, indent=2))
    print(f"wrote {out}")
