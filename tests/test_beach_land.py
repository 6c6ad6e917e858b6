"""The land behind a slope beach (water/land.py): the foreshore's plane up to the berm, a backshore,
a foredune ridge with grass, drawn by the sea pass and answered by the host's height queries alike.

A beach seen from the sea or from the sand ended in flat sand at the water level out to the horizon;
a sandy beach rises to a berm 1-3 m above the sea and ends at foredunes 2-20 m high held by marram
grass (Komar, Beach Processes and Sedimentation, fig. 2-1; Short 1999)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from igserver.cigi.queries import land_height, surface_height
from igserver.render.camera import make_view
from igserver.scene import apply_patch
from igserver.scene.files import load_scene
from igserver.water.land import land_elevation, profile

from helpers import with_and_without_skip

# From the sand 20 m above the still-water line (x = 420; the shore runs north at x = 400), looking
# east, inland, level: the backshore and the foredune ridge ahead.
INLAND = {"camera": {"position": [420.0, -120.0, 3.0], "heading": 90.0, "pitch": 0.0, "fov_y": 40.0,
                     "width": 240, "height": 135, "exposure_ev": 14.5}, "time": {"sim_time": 100.0}}


def world_points(renderer, scene) -> tuple[np.ndarray, np.ndarray]:
    """(world xyz per pixel from the distance target, NaN for the sky; elevation angle per pixel, deg)."""
    renderer.render(scene)
    view = make_view(scene.camera)
    return view.pixel_world(renderer.read_distance(), 5e3), np.degrees(np.arcsin(view.pixel_rays()[..., 2]))


def test_profile_rises_from_the_sea_bed_to_the_dunes():
    """The bed's plane continued up to the berm, a near-flat backshore, a ridge of the dune's height
    (within its along-shore variation, +-30 %) that falls back to 70 % of it inland; continuous."""
    beta, berm, dune = 0.02, 2.0, 8.0
    s = np.linspace(-50.0, 600.0, 6501)
    z = profile(s, np.zeros_like(s), beta, berm, dune)
    assert np.allclose(z[s <= 100.0], beta * s[s <= 100.0])
    assert np.max(np.abs(np.diff(z))) < 0.05  # no step at 0.1 m spacing
    assert 0.7 * dune < z.max() - berm < 1.35 * dune
    flat = profile(s, np.zeros_like(s), beta, berm, 0.0)  # the land without the dune: level behind the backshore
    assert flat.max() < berm + 0.005 * 1.3 * 40.0 + 1e-9 and flat[-1] == flat.max()
    assert z[-1] - flat[-1] == pytest.approx(0.7 * (z.max() - flat[-1]), abs=0.3)  # the hinterland


def test_the_drawn_land_is_the_queried_land(renderer):
    """Every pixel of land within 150 m (world point from the distance target) lies on the profile the
    host's HOT query answers: the mesh's linear interpolation between vertices departs from the
    smooth ridge by at most 0.25 m there (the near blocks' spacing is metres); and there is land
    above the eye's horizontal (before: flat sand below it, the sky from 0 deg up)."""
    scene = apply_patch(load_scene("sea_beach"), INLAND)
    world, elevation = world_points(renderer, scene)
    near = np.isfinite(world[..., 0]) & (np.hypot(world[..., 0] - 420.0, world[..., 1] + 120.0) < 150.0)
    land = near & (land_elevation(scene.ocean.bathymetry, world[..., :2]) > 0.3)
    assert land.sum() > 2000
    want = land_elevation(scene.ocean.bathymetry, world[land][:, :2])
    err = np.abs(world[land][:, 2] - want)
    assert np.percentile(err, 99) < 0.25, np.percentile(err, [50, 99])
    hot = land_height(scene, world[land][:, :2])[0]
    assert np.allclose(hot, want)
    # the dune ridge stands above the horizontal: land in most columns at +0.5 deg and more
    above = np.isfinite(world[..., 0]) & (elevation > 0.5)
    assert above.any(axis=0).mean() > 0.8


def test_dunes_carry_grass_and_the_beach_is_bare(renderer):
    """Dune grass (marram, yellow-green) from the ridge's rise on: the ridge's pixels are greener
    (green over red, sRGB) than the backshore's sand by over 0.03 (0.05 measured: the face seen from
    the beach is the ridge's lower half, where the grass thins out toward the bare backshore; bare
    sand everywhere gives equal ratios within 0.01)."""
    scene = apply_patch(load_scene("sea_beach"), INLAND)
    rgb = renderer.render(scene).rgba[..., :3].astype(np.float64)
    world, _ = world_points(renderer, scene)
    z = land_elevation(scene.ocean.bathymetry, np.nan_to_num(world[..., :2]))
    ok = np.isfinite(world[..., 0])
    ridge = ok & (z > 6.0)
    sand = ok & (z > 1.0) & (z < 2.2)
    assert ridge.sum() > 100 and sand.sum() > 100
    green = lambda m: float(np.mean(rgb[m][:, 1] / np.maximum(rgb[m][:, 0], 1.0)))
    assert green(ridge) > green(sand) + 0.03, (green(ridge), green(sand))


def test_line_of_sight_is_blocked_by_the_dune():
    """From the beach at 1.5 m to a point 1.5 m up 300 m inland, the ridge between them blocks the
    line of sight; over the sea the surface height is the sea's."""
    scene = apply_patch(load_scene("sea_beach"), {"time": {"sim_time": 100.0}})
    xs = np.linspace(410.0, 700.0, 300)
    pts = np.column_stack([xs, np.zeros_like(xs)])
    ground = surface_height(scene, pts)
    eye, target = np.array([410.0, 0.0, ground[0] + 1.5]), np.array([700.0, 0.0, ground[-1] + 1.5])
    line = eye[2] + (target[2] - eye[2]) * (xs - 410.0) / 290.0
    assert np.any(ground > line)
    sea = surface_height(scene, np.array([[0.0, 0.0]]))
    assert math.isfinite(sea[0]) and abs(sea[0]) < 3.0


@pytest.mark.parametrize("bathymetry", [
    None,  # sea_beach's slope beach
    {"type": "map", "map": "island", "map_center": [300.0, 0.0], "map_size": [1500.0, 1500.0],
     "map_elevation": [-30.0, 12.0], "depth": 30.0}])
def test_offshore_blocks_leave_the_land_out(renderer, bathymetry):
    """Blocks whose rest square lies wholly under the water (shore.py blocks_reaching_land) are drawn by
    the program without the swash and the land (llvmpipe runs every branch of a fragment shader on
    every pixel: the land's code cost a beach's water pass a quarter). The picture is bit-identical to
    the one drawn with that code in every block, and some blocks are drawn without it."""
    patch = {"camera": {"position": [330.0, -120.0, 8.0], "heading": 60.0, "pitch": -10.0,
                        "width": 240, "height": 135}, "time": {"sim_time": 100.0}}
    if bathymetry is not None:
        patch["ocean"] = {"bathymetry": bathymetry}
    fast, full, stats = with_and_without_skip(renderer, apply_patch(load_scene("sea_beach"), patch), "skip_offshore_land")
    assert 0 < stats["land_blocks"] < stats["blocks"], stats
    assert np.array_equal(fast, full)
