"""The top of a fog layer seen from above: soft relief from its undulations, lit by the sun.

A fog or stratus top is not a plane: it heaves in cells a few hundred metres across and some metres
to tens of metres high (Stull, "An Introduction to Boundary Layer Meteorology", 1988, ch. 11:
stratocumulus and fog tops undulate by ~10 % of the layer's depth), and sunlight on its slopes draws
them out as a soft brightness pattern. The layer's own light is the two-stream model's (sky/haze.py,
checked in test_atmosphere_light.py); the relief only redistributes it."""

from __future__ import annotations

import numpy as np
import pytest

from igserver.photometry import LUMA
from igserver.render.frame import build_frame
from igserver.scene import apply_patch
from igserver.scene.files import load_scene


def fog_scene(z: float = 500.0, pitch: float = -20.0, fog_top: float | None = 150.0, x: float = 0.0):
    atmosphere = {"visibility": 300.0, "visibility_transition": 0.0}
    if fog_top is not None:
        atmosphere["fog_top"] = fog_top
    return apply_patch(load_scene("sea_beaufort5"), {
        "atmosphere": atmosphere, "time": {"utc": "2026-06-21T11:40:00Z"},
        "camera": {"position": [x, 0.0, z], "pitch": pitch, "fov_y": 30.0, "width": 160, "height": 90,
                   "exposure_ev": 15.0}})


def fog_luminance(renderer, s) -> np.ndarray:
    renderer.render(s)
    frame = build_frame(renderer.ctx, s)
    return (renderer.read_hdr()[..., :3] / frame.exposure) @ LUMA


def relief_contrast(lum: np.ndarray) -> float:
    """Relative standard deviation of the fog's luminance about a smooth version of it (each row
    over its own mean: the view's slow gradient with distance removed), rows 30..80 of 90 (the fog
    top 25-34 deg below the horizon's level in this 30 deg field)."""
    region = lum[30:80]
    return float((region / region.mean(axis=1, keepdims=True)).std())


def test_a_sunlit_fog_top_seen_from_above_shows_soft_relief(renderer):
    # Bounds: at least 3 % (the flat layer: 0.5 %, the sea's waves seen through 6 optical depths
    # of fog) and at most 20 % ("soft": multiple scattering in the top smooths the shading of its
    # slopes; a Lambertian surface with the same slopes under this sun would vary by ~25 %).
    c = relief_contrast(fog_luminance(renderer, fog_scene()))
    assert 0.03 < c < 0.2, c


def test_the_relief_is_fixed_in_the_world(renderer):
    # The pattern belongs to the fog, not to the camera: moved 1 km east and back by the same
    # amount of view, the relief moves with it (a camera-relative pattern would repeat the frame).
    a = fog_luminance(renderer, fog_scene())
    b = fog_luminance(renderer, fog_scene(x=1000.0))
    assert np.abs(a[30:80] / b[30:80] - 1.0).mean() > 0.02


@pytest.mark.parametrize("z, pitch, fog_top", [(100.0, -8.0, 150.0), (500.0, -20.0, None)])
def test_no_relief_from_inside_the_fog_or_without_a_top(renderer, z, pitch, fog_top):
    # From inside the layer, or in haze without a top, there is no top to see: the frame is the
    # layer's smooth light (relative scatter below 1 %; measured 0.5 %: the sea's waves through
    # 3-10 optical depths of fog).
    c = relief_contrast(fog_luminance(renderer, fog_scene(z=z, fog_top=fog_top, pitch=pitch)))
    assert c < 0.01, c



GRAD_PROBE = """
#include "common/noise.glsl"
layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer Points { vec4 points[]; };
layout(std430, binding = 1) writeonly buffer Values { vec4 values[]; };
layout(std430, binding = 2) writeonly buffer Plain { float plain[]; };
void main() {
    uint i = gl_GlobalInvocationID.x;
    vec3 period = vec3(64.0, 64.0, 0.0);
    values[i] = turbulence3_grad(points[i].xyz, period, 2, 23u);
    plain[i] = turbulence3(points[i].xyz, period, 2, 23u);
}
"""


def test_the_reliefs_noise_gradient_is_the_noises_slope(renderer):
    # The relief shades by the gradient of the project's noise, computed with its value over the same
    # corners (common/noise.glsl turbulence3_grad): its value is turbulence3's, and its gradient the
    # central difference of turbulence3 at h = 1e-2 lattice units (the curvature's error ~h^2 x the
    # third derivative, and float32 differences ~1e-5 / h, against slopes of a few: bound 0.05).
    from igserver.render import shaders

    src = shaders._INCLUDE.sub(lambda m: shaders.expand(m.group(1)), GRAD_PROBE)
    probe = renderer.ctx.compute_shader(shaders.GLSL_VERSION + "\n" + src)
    n, h = 256, 1e-2
    base = np.random.default_rng(1).uniform(0.0, 64.0, (n, 3))
    points = [base] + [base + s * h * np.eye(3)[a] for a in range(3) for s in (1.0, -1.0)]
    data = np.zeros((len(points) * n, 4), np.float32)
    data[:, :3] = np.concatenate(points)
    buffers = [renderer.ctx.buffer(data.tobytes()), renderer.ctx.buffer(reserve=data.nbytes),
               renderer.ctx.buffer(reserve=len(data) * 4)]
    for binding, buf in enumerate(buffers):
        buf.bind_to_storage_buffer(binding)
    probe.run(len(data) // 64)
    grad = np.frombuffer(buffers[1].read(), np.float32).reshape(len(points), n, 4)[0]
    plain = np.frombuffer(buffers[2].read(), np.float32).reshape(len(points), n)
    for buf in buffers:
        buf.release()
    probe.release()
    assert np.abs(grad[:, 0] - plain[0]).max() < 1e-5
    central = np.stack([(plain[1 + 2 * a] - plain[2 + 2 * a]) / (2.0 * h) for a in range(3)], axis=1)
    assert np.abs(grad[:, 1:] - central).max() < 0.05, np.abs(grad[:, 1:] - central).max()
    assert np.abs(central).max() > 1.0  # the slopes are not all flat
