"""``igserver quality surfaces``: the BRDF's energy and precision, shadow maps' error against run time.

1. White furnace: the directional albedo  a(v) = integral of brdf_cos over the hemisphere  of the
   project's BRDF (common/brdf.glsl, re-stated here in float64 numpy) for a white base colour, for
   every roughness x metallic x view angle. Energy conservation demands a <= 1. Integrated by
   importance sampling (GGX normal sampling for the specular lobe, cosine sampling for the
   diffuse lobe; 2^18 stratified samples each, so the estimate's 3-sigma error is ~ 0.5 %).
2. Shader vs numpy: the GLSL brdf_cos rendered into a float32 target (surfaces/brdf_probe.frag.glsl)
   at thousands of (view, light, azimuth, roughness, metallic, colour) samples, against the same
   formula in float64: max relative error where the value is significant (> 1e-3 of the sample's
   peak), and the max absolute error elsewhere.
3. Shadows: the surfaces pass at shadow-map resolutions x PCF taps against a 4096 px / 64-tap
   reference of the same frame (a boat and a box on the ground, sun at 20 deg): RMSE of the
   linear HDR frame (relative to the mean of the reference) against the median ms of the
   surfaces pass.

Usage: igserver quality surfaces [--out out/quality_surfaces.md] [--size 320x180] [--frames 3]
       [--resolutions 512,1024,2048,4096] [--taps 1,4,8,16]
"""

from __future__ import annotations

import argparse
import json
import math
import re
import statistics
from pathlib import Path

import numpy as np

MIN_ALPHA = 2e-3  # as in common/brdf.glsl
# The specular lobe's albedo tables the shader reads; brdf_tables.py generates them from this BRDF.
BRDF_TABLES_GLSL = Path(__file__).resolve().parent.parent / "render" / "common" / "brdf_tables.glsl"


# --- the BRDF in float64 (the same formula as common/brdf.glsl) ------------------------------------
_TABLES: dict | None = None


def read_tables(path: Path = BRDF_TABLES_GLSL) -> dict[str, np.ndarray]:
    """The constants as the shader sees them (parsed back from the GLSL file): A, B (N x N, rows
    roughness, columns sqrt(N.V)) and A_AVG, B_AVG (N, per roughness)."""
    text = path.read_text()
    n = int(re.search(r"const int BRDF_TABLE_N = (\d+);", text).group(1))
    out = {}
    for name, body in re.findall(r"const float BRDF_TABLE_(\w+)\[\d+\] = float\[\]\(([^)]*)\)", text):
        values = np.array([float(x) for x in body.split(",")])
        out[name] = values.reshape(n, n) if values.size == n * n else values
    return out


def _tables() -> dict:
    global _TABLES
    if _TABLES is None:
        _TABLES = read_tables()
    return _TABLES


def _bilinear(table: np.ndarray, mu, roughness):
    """Bilinear lookup exactly as common/brdf.glsl's brdf_table (rows roughness, columns N.V)."""
    n = table.shape[0]
    x = np.sqrt(np.clip(np.asarray(mu, np.float64), 0.0, 1.0)) * (n - 1)
    y = np.clip(np.asarray(roughness, np.float64), 0.0, 1.0) * (n - 1)
    i0 = np.minimum(np.floor(x), n - 2).astype(int)
    j0 = np.minimum(np.floor(y), n - 2).astype(int)
    fx, fy = x - i0, y - j0
    top = table[j0, i0] * (1 - fx) + table[j0, i0 + 1] * fx
    bottom = table[j0 + 1, i0] * (1 - fx) + table[j0 + 1, i0 + 1] * fx
    return top * (1 - fy) + bottom * fy


def specular_albedo(f0, roughness, mu):
    """E_s = F0 A + B from the tables (per channel: f0 (..., 3))."""
    t = _tables()
    a = _bilinear(t["A"], mu, roughness)[..., None]
    b = _bilinear(t["B"], mu, roughness)[..., None]
    return np.asarray(f0) * a + b


def average_albedo(f0, roughness):
    t = _tables()
    n = t["A_AVG"].size
    y = np.clip(np.asarray(roughness, np.float64), 0.0, 1.0) * (n - 1)
    j0 = np.minimum(np.floor(y), n - 2).astype(int)
    fy = y - j0
    a = (t["A_AVG"][j0] * (1 - fy) + t["A_AVG"][j0 + 1] * fy)[..., None]
    b = (t["B_AVG"][j0] * (1 - fy) + t["B_AVG"][j0 + 1] * fy)[..., None]
    return np.asarray(f0) * a + b


def brdf_terms(base, metallic, roughness, n_dot_v, n_dot_l, n_dot_h, v_dot_h):
    """(diffuse, specular) lobes x N.L, per channel; arrays broadcast; base (..., 3)."""
    base = np.asarray(base, np.float64)
    metallic_b = np.asarray(metallic, np.float64)[..., None]
    alpha = np.maximum(np.asarray(roughness, np.float64) ** 2, MIN_ALPHA)
    a2 = alpha * alpha
    n_dot_v = np.maximum(n_dot_v, 1e-4)
    n_dot_h = np.maximum(n_dot_h, 0.0)
    d = n_dot_h**2 * (a2 - 1.0) + 1.0
    ggx = a2 / (math.pi * d * d)
    gv = n_dot_l * np.sqrt(n_dot_v**2 * (1.0 - a2) + a2)
    gl = n_dot_v * np.sqrt(n_dot_l**2 * (1.0 - a2) + a2)
    vis = 0.5 / np.maximum(gv + gl, 1e-6)
    f0 = 0.04 * (1.0 - metallic_b) + base * metallic_b
    m = np.clip(1.0 - np.maximum(v_dot_h, 0.0), 0.0, 1.0)[..., None]
    f = f0 + (1.0 - f0) * m**5
    lit = (np.asarray(n_dot_l) > 0.0)[..., None]
    cos_l = np.asarray(n_dot_l)[..., None]
    spec = np.where(lit, f * (ggx * vis)[..., None] * cos_l, 0.0)
    if np.all(np.asarray(metallic) >= 1.0):
        diffuse = np.zeros_like(spec)
    else:
        f0_full = np.broadcast_to(f0, np.broadcast_shapes(np.shape(f0), spec.shape))
        e_v = specular_albedo(f0_full, roughness, n_dot_v)
        e_l = specular_albedo(f0_full, roughness, np.maximum(n_dot_l, 0.0))
        e_avg = average_albedo(f0_full, roughness)
        diffuse = (1.0 - e_v) * (1.0 - e_l) / np.maximum(1.0 - e_avg, 1e-6) * (1.0 - metallic_b) * base / math.pi
    return np.where(lit, diffuse * cos_l, 0.0), spec


def brdf_cos(base, metallic, roughness, n_dot_v, n_dot_l, n_dot_h, v_dot_h):
    """BRDF x N.L (the GLSL brdf_cos), per channel."""
    diffuse, spec = brdf_terms(base, metallic, roughness, n_dot_v, n_dot_l, n_dot_h, v_dot_h)
    return diffuse + spec


def _angles_to_dots(theta_v, theta_l, phi):
    v = np.stack([np.sin(theta_v), np.zeros_like(theta_v), np.cos(theta_v)], -1)
    l = np.stack([np.sin(theta_l) * np.cos(phi), np.sin(theta_l) * np.sin(phi), np.cos(theta_l)], -1)
    h = v + l
    h /= np.linalg.norm(h, axis=-1, keepdims=True)
    return v[..., 2], l[..., 2], h[..., 2], np.sum(v * h, -1)


def ggx_half_vectors(roughness: float, samples: int, seed: int = 1234) -> tuple[np.ndarray, np.ndarray]:
    """Stratified half vectors from the GGX distribution and their pdf D(h) cos(theta_h)."""
    rng = np.random.default_rng(seed)
    k = int(math.isqrt(samples))
    u1 = ((np.arange(k)[:, None] + rng.random((k, k))) / k).reshape(-1)
    u2 = ((np.arange(k)[None, :] + rng.random((k, k))) / k).reshape(-1)
    alpha = max(roughness**2, MIN_ALPHA)
    cos_h = np.sqrt((1.0 - u1) / (1.0 + (alpha**2 - 1.0) * u1))
    sin_h = np.sqrt(np.maximum(1.0 - cos_h**2, 0.0))
    phi = 2 * math.pi * u2
    h = np.stack([sin_h * np.cos(phi), sin_h * np.sin(phi), cos_h], -1)
    a2 = alpha**2
    d = cos_h**2 * (a2 - 1.0) + 1.0
    return h, (a2 / (math.pi * d * d)) * cos_h


def directional_albedo(roughness: float, metallic: float, theta_v: float, samples: int = 2**18,
                       base=(1.0, 1.0, 1.0)) -> float:
    """Integral of brdf_cos over the light hemisphere (max over channels), importance sampled."""
    rng = np.random.default_rng(1234)
    k = int(math.isqrt(samples))
    u1 = ((np.arange(k)[:, None] + rng.random((k, k))) / k).reshape(-1)
    u2 = ((np.arange(k)[None, :] + rng.random((k, k))) / k).reshape(-1)
    phi = 2 * math.pi * u2
    base = np.asarray(base, float)
    v = np.array([math.sin(theta_v), 0.0, math.cos(theta_v)])
    # specular lobe: half vectors from the GGX distribution
    h, pdf_h = ggx_half_vectors(roughness, samples)
    cos_h = h[:, 2]
    v_dot_h = h @ v
    l = 2.0 * v_dot_h[:, None] * h - v
    pdf_l = pdf_h / np.maximum(4.0 * v_dot_h, 1e-12)
    _, spec = brdf_terms(base, metallic, roughness, v[2], l[:, 2], cos_h, v_dot_h)
    spec = spec / pdf_l[:, None]
    # diffuse lobe: cosine-weighted light directions, pdf = cos / pi
    r = np.sqrt(u1)
    l2 = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(np.maximum(1.0 - u1, 0.0))], -1)
    h2 = l2 + v
    h2 /= np.linalg.norm(h2, axis=-1, keepdims=True)
    diff, _ = brdf_terms(base, metallic, roughness, v[2], l2[:, 2], h2[:, 2], h2 @ v)
    diff = diff * math.pi / np.maximum(l2[:, 2:3], 1e-12)
    return float(np.max(spec.mean(axis=0) + diff.mean(axis=0)))


def furnace(roughnesses=(0.02, 0.1, 0.25, 0.5, 0.75, 1.0), metallics=(0.0, 0.5, 1.0),
            view_degrees=(0, 30, 60, 80, 89), samples: int = 2**18) -> list[dict]:
    rows = []
    for r in roughnesses:
        for m in metallics:
            albedo = [directional_albedo(r, m, math.radians(t), samples) for t in view_degrees]
            rows.append({"roughness": r, "metallic": m, "max_albedo": max(albedo),
                         "albedo_by_view": dict(zip(view_degrees, albedo))})
    return rows


# --- the shader's BRDF ----------------------------------------------------------------------------
def brdf_samples(width: int = 128, height: int = 64, seed: int = 7) -> tuple[np.ndarray, np.ndarray]:
    """(angles (h, w, 4): theta_v, theta_l, phi, roughness; material (h, w, 4): metallic, rgb)."""
    rng = np.random.default_rng(seed)
    n = width * height
    angles = np.stack([rng.uniform(0.0, math.radians(89.0), n), rng.uniform(0.0, math.radians(89.0), n),
                       rng.uniform(0.0, math.pi, n), rng.choice([0.05, 0.1, 0.2, 0.35, 0.5, 0.7, 1.0], n)], -1)
    material = np.concatenate([rng.choice([0.0, 0.5, 1.0], n)[:, None], rng.uniform(0.02, 1.0, (n, 3))], -1)
    return angles.reshape(height, width, 4).astype(np.float32), material.reshape(height, width, 4).astype(np.float32)


def shader_brdf(ctx, programs, angles: np.ndarray, material: np.ndarray) -> np.ndarray:
    """Evaluate common/brdf.glsl per sample on the GPU into a float32 target; returns (h, w, 3)."""
    import moderngl

    from ..render.bindings import use_texture
    from ..render.shaders import set_uniforms

    h, w = angles.shape[:2]
    tex_a = ctx.texture((w, h), 4, angles.tobytes(), dtype="f4")
    tex_m = ctx.texture((w, h), 4, material.tobytes(), dtype="f4")
    target = ctx.texture((w, h), 4, dtype="f4")
    fbo = ctx.framebuffer([target])
    try:
        program = programs.program("common/fullscreen.vert.glsl", "surfaces/brdf_probe.frag.glsl")
        use_texture(tex_a, 0)
        use_texture(tex_m, 1)
        set_uniforms(program, {"u_angles": 0, "u_material": 1})
        fbo.use()
        ctx.disable(moderngl.DEPTH_TEST | moderngl.BLEND)
        ctx.vertex_array(program, []).render(moderngl.TRIANGLES, vertices=3)
        out = np.frombuffer(fbo.read(components=4, dtype="f4"), np.float32).reshape(h, w, 4)[..., :3]
    finally:
        for obj in (fbo, target, tex_a, tex_m):
            obj.release()
    return out.astype(np.float64)


def numpy_brdf(angles: np.ndarray, material: np.ndarray) -> np.ndarray:
    a = angles.astype(np.float64)
    m = material.astype(np.float64)
    nv, nl, nh, vh = _angles_to_dots(a[..., 0], a[..., 1], a[..., 2])
    return brdf_cos(m[..., 1:4], m[..., 0], a[..., 3], nv, nl, nh, vh)


def brdf_errors(shader: np.ndarray, reference: np.ndarray) -> dict:
    """Relative error where the value is significant (> 1e-3 of the largest), absolute elsewhere."""
    scale = float(np.max(np.abs(reference)))
    significant = np.abs(reference) > 1e-3 * scale
    rel = np.abs(shader - reference)[significant] / np.abs(reference)[significant]
    absolute = np.abs(shader - reference)[~significant]
    return {"samples": int(reference[..., 0].size), "max_relative": float(rel.max()), "p99_relative": float(np.quantile(rel, 0.99)),
            "max_absolute_small": float(absolute.max()) if absolute.size else 0.0, "peak": scale,
            "finite": bool(np.all(np.isfinite(shader)))}


# --- shadows --------------------------------------------------------------------------------------
def shadow_scene(width: int, height: int):
    from ..scene.model import Scene

    return Scene.model_validate({
        "camera": {"position": [6.0, -26.0, 9.0], "heading": -10.0, "pitch": -16.0, "fov_y": 50.0,
                   "width": width, "height": height, "exposure_ev": 14.0},
        "time": {"utc": "2026-06-15T10:00:00Z", "sun_override": {"elevation": 20.0, "azimuth": 250.0}},
        "ground": {"enabled": True, "level": 0.0, "color": [0.4, 0.4, 0.38]},
        "entities": [
            {"id": "boat", "model": "patrol_boat", "position": [0.0, 10.0, 1.8], "heading": 80.0},
            {"id": "box", "model": "box", "position": [8.0, -4.0, 0.0], "scale": [2.0, 2.0, 4.0]},
            {"id": "crate", "model": "crate", "position": [3.0, -8.0, 0.0], "heading": 30.0},
        ],
    })


def shadow_table(renderer, width: int, height: int, resolutions: list[int], taps_list: list[int],
                 frames: int) -> tuple[float, list[dict]]:
    """(reference ms, rows of resolution, taps, relative RMSE against 4096 px / 64 taps, median ms)."""
    from ..scene import apply_patch

    surfaces = renderer.graph.passes["surfaces"]
    default_taps = surfaces.shadow_taps
    base = shadow_scene(width, height)

    def render(resolution: int, taps: int) -> tuple[np.ndarray, float]:
        surfaces.shadow_taps = taps
        scene = apply_patch(base, {"shadows": {"resolution": resolution}})
        renderer.render(scene)  # compile / warm
        times = [renderer.render(scene, timed=True).pass_ms["surfaces"] for _ in range(frames)]
        return renderer.read_hdr()[..., :3].astype(np.float64), statistics.median(times)

    try:
        reference, ref_ms = render(4096, 64)
        mean = float(np.mean(reference))
        table = []
        for res in resolutions:
            for taps in taps_list:
                img, ms = render(res, taps)
                rmse = float(np.sqrt(np.mean((img - reference) ** 2))) / mean
                table.append({"resolution": res, "taps": taps, "rel_rmse": rmse, "ms": ms})
                print(f"| {res} | {taps} | {rmse:.4f} | {ms:.1f} |", flush=True)
    finally:
        surfaces.shadow_taps = default_taps
    return ref_ms, table


def study(quick: bool = False):
    """For `igserver quality` (report.py): shadow-map resolution x PCF taps, error against ms; the
    BRDF's furnace and precision checks as notes."""
    from ..render.renderer import Renderer
    from ..render.surfaces.surfaces import DEFAULT_SHADOW_TAPS
    from ..scene.model import Shadows
    from .report import Point, Study

    width, height = (160, 90) if quick else (320, 180)
    renderer = Renderer()
    try:
        angles, material = brdf_samples(64, 32) if quick else brdf_samples()
        errs = brdf_errors(shader_brdf(renderer.ctx, renderer.programs, angles, material),
                           numpy_brdf(angles, material))
        rows = furnace(samples=2**14 if quick else 2**18)
        ref_ms, table = shadow_table(renderer, width, height, [512, 1024, 2048] if quick else [512, 1024, 2048, 4096],
                                     [1, 4, 8] if quick else [1, 4, 8, 16], 1 if quick else 3)
        device = renderer.caps.renderer
    finally:
        renderer.release()
    default_res = Shadows().resolution
    points = [Point("shadow map px" if r["taps"] == DEFAULT_SHADOW_TAPS else f"px at {r['taps']} taps",
                    f"{r['resolution']} px, {r['taps']} taps", r["rel_rmse"], r["ms"],
                    "medium" if (r["resolution"], r["taps"]) == (default_res, DEFAULT_SHADOW_TAPS) else None)
              for r in table]
    worst = max(rows, key=lambda r: r["max_albedo"])
    notes = [f"white furnace: max directional albedo {worst['max_albedo']:.4f} (roughness {worst['roughness']},"
             f" metallic {worst['metallic']}); <= 1 means energy is conserved",
             f"shader BRDF vs float64 numpy: max relative error {errs['max_relative']:.2e} over {errs['samples']} samples",
             f"reference: 4096 px, 64 taps ({ref_ms:.1f} ms)"]
    return Study("surfaces", "relative RMSE of the linear frame against the 4096 px / 64-tap shadow reference",
                 f"ms, surfaces pass at {width}x{height} (median)", points, notes, device)


def run(argv: list[str]) -> int:
    from ..render.renderer import Renderer

    parser = argparse.ArgumentParser(prog="igserver quality surfaces", description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("out/quality_surfaces.md"))
    parser.add_argument("--size", default="320x180")
    parser.add_argument("--frames", type=int, default=3)
    parser.add_argument("--resolutions", default="512,1024,2048,4096")
    parser.add_argument("--taps", default="1,4,8,16")
    args = parser.parse_args(argv)
    width, height = (int(x) for x in args.size.lower().split("x"))

    lines = ["# Surfaces quality: BRDF energy and precision, shadow maps (error vs ms)", ""]
    rows = furnace()
    worst = max(rows, key=lambda r: r["max_albedo"])
    lines += ["## White furnace (directional albedo of a white material, max over view angles 0..89 deg)", "",
              "| roughness | metallic | max albedo |", "|---|---|---|"]
    lines += [f"| {r['roughness']} | {r['metallic']} | {r['max_albedo']:.4f} |" for r in rows]
    lines += ["", f"Largest: {worst['max_albedo']:.4f} (roughness {worst['roughness']}, metallic {worst['metallic']}); "
              f"energy conservation holds when <= 1 (Monte Carlo 3-sigma ~ 0.005).", ""]

    renderer = Renderer()
    angles, material = brdf_samples()
    errs = brdf_errors(shader_brdf(renderer.ctx, renderer.programs, angles, material), numpy_brdf(angles, material))
    lines += ["## Shader BRDF vs float64 numpy", "", "```", json.dumps(errs, indent=1), "```", ""]

    ref_ms, table = shadow_table(renderer, width, height, [int(x) for x in args.resolutions.split(",")],
                                 [int(x) for x in args.taps.split(",")], args.frames)
    lines += [f"## Shadow maps ({width}x{height}; reference 4096 px, 64 taps: {ref_ms:.1f} ms)", "",
              "| resolution | taps | relative RMSE | surfaces ms |", "|---|---|---|---|"]
    lines += [f"| {r['resolution']} | {r['taps']} | {r['rel_rmse']:.4f} | {r['ms']:.1f} |" for r in table]
    lines += ["", f"Renderer: {renderer.caps.renderer}. Times are wall time around ctx.finish() (llvmpipe has no"
              " usable timer queries); on a shared machine they are inflated.", ""]
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text("\n".join(lines))
    args.out.with_suffix(".json").write_text(json.dumps({"furnace": rows, "brdf": errs, "shadows": table}, indent=1))
    print("\n".join(lines))
    print(f"wrote {args.out}")
    return 0
