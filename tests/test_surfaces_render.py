"""Surfaces on the GPU: the BRDF shader against float64 numpy, the white furnace, a metal sphere
against a dielectric one, shadows where the geometry puts them, 32 lights, articulated parts."""

from __future__ import annotations

import math

import numpy as np
import pytest

from igserver.assets import gltf
from igserver.photometry import LUMA
from igserver.quality import surfaces as study
from igserver.render.camera import make_view
from igserver.render.frame import MAX_LIGHTS
from igserver.render.lights import gather_lights
from igserver.scene.model import Scene


def _scene(data: dict) -> Scene:
    return Scene.model_validate(data)


def _pixel(scene: Scene, world) -> tuple[int, int]:
    """(row, col) of a world point in the frame (rows top first, as read_hdr returns them)."""
    view = make_view(scene.camera)
    clip = view.view_proj @ np.append(view.relative(world), 1.0)
    ndc = clip[:3] / clip[3]
    col = int((ndc[0] * 0.5 + 0.5) * scene.camera.width)
    row = int((0.5 - ndc[1] * 0.5) * scene.camera.height)
    assert 0 <= row < scene.camera.height and 0 <= col < scene.camera.width, "test point off screen"
    return row, col


def _lum(hdr: np.ndarray, row: int, col: int, r: int = 1) -> float:
    patch = hdr[max(row - r, 0):row + r + 1, max(col - r, 0):col + r + 1, :3]
    return float(np.mean(patch @ LUMA))


def test_brdf_shader_matches_float64_numpy(renderer):
    angles, material = study.brdf_samples(64, 32)
    shader = study.shader_brdf(renderer.ctx, renderer.programs, angles, material)
    errors = study.brdf_errors(shader, study.numpy_brdf(angles, material))
    assert errors["finite"]
    # float32 evaluation of ~30 operations, none cancelling (GGX is written with |N x H|^2):
    # ~30 x 6e-8 ~ 2e-6 expected; 1e-4 leaves room for GPUs whose sqrt/exp are a few ulp off.
    assert errors["max_relative"] < 1e-4, errors
    assert errors["max_absolute_small"] < 1e-4 * errors["peak"], errors


def test_white_furnace_reflects_at_most_the_incident_energy():
    rows = study.furnace(roughnesses=(0.02, 0.1, 0.5, 1.0), metallics=(0.0, 0.5, 1.0),
                         view_degrees=(0, 60, 80, 89), samples=2**14)
    worst = max(r["max_albedo"] for r in rows)
    # Energy conservation: albedo <= 1. The diffuse lobe takes exactly what the specular lobe leaves
    # up to the bilinear interpolation of a 16 x 16 table, worst for a near-mirror seen at 89 deg
    # (~1 %), plus the Monte Carlo error of 2^14 stratified samples (~0.3 %): 2 % in all.
    assert worst <= 1.02, max(rows, key=lambda r: r["max_albedo"])
    # and not trivially dark: a white dielectric reflects nearly all light at every roughness
    assert min(r["max_albedo"] for r in rows if r["metallic"] == 0.0) > 0.95


@pytest.fixture()
def spheres_dir(tmp_path, monkeypatch):
    import trimesh
    from trimesh.visual.material import PBRMaterial

    folder = tmp_path / "models"
    folder.mkdir()
    for name, color, metallic, roughness in (("gold_sphere", [1.0, 0.78, 0.34, 1.0], 1.0, 0.25),
                                             ("white_sphere", [0.8, 0.8, 0.8, 1.0], 0.0, 0.5)):
        mesh = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
        mesh.visual = trimesh.visual.TextureVisuals(uv=np.zeros((len(mesh.vertices), 2)), material=PBRMaterial(
            baseColorFactor=color, metallicFactor=metallic, roughnessFactor=roughness))
        (folder / f"{name}.glb").write_bytes(trimesh.Scene(mesh).export(file_type="glb"))
    monkeypatch.setenv("IGSERVER_ASSETS", str(tmp_path))
    gltf._cache.clear()
    yield folder
    gltf._cache.clear()


def test_metal_sphere_against_dielectric_sphere(renderer, spheres_dir):
    scene = _scene({
        "camera": {"position": [0, -8, 1.5], "heading": 0, "pitch": 0, "fov_y": 40, "width": 128, "height": 72,
                   "exposure_ev": 14},
        "time": {"utc": "2026-06-15T10:00:00Z", "sun_override": {"elevation": 35, "azimuth": 200}},
        "ground": {"enabled": True, "level": 0.0},
        "entities": [{"id": "gold", "model": "gold_sphere", "position": [-1.3, 0, 1.5]},
                     {"id": "white", "model": "white_sphere", "position": [1.3, 0, 1.5]}],
    })
    renderer.render(scene)
    hdr = renderer.read_hdr()
    assert np.all(np.isfinite(hdr))

    def sphere_rgb(center):
        row, col = _pixel(scene, center)
        return hdr[row - 3:row + 4, col - 3:col + 4, :3].reshape(-1, 3).mean(axis=0)

    gold, white = sphere_rgb([-1.3, 0, 1.5]), sphere_rgb([1.3, 0, 1.5])
    # A metal reflects its surroundings tinted by F0 = base colour (gold: R/B = 1/0.34 ~ 2.9); a white
    # dielectric reflects the light's own colour. So the gold sphere's red/blue ratio must exceed the
    # white one's by well over 1.5 (the margin covers Schlick's whitening at grazing angles).
    assert (gold[0] / gold[2]) > 1.5 * (white[0] / white[2]), (gold, white)
    # The dielectric is shaded by the sun: the side toward the sun is several times brighter than
    # the side away from it (sun ~ 5x the sky's irradiance at 35 deg; only sky light on the far side).
    sun = np.array([math.sin(math.radians(200)) * math.cos(math.radians(35)),
                    math.cos(math.radians(200)) * math.cos(math.radians(35)), math.sin(math.radians(35))])
    view_dir = np.array([0.0, -1.0, 0.0])  # toward the camera
    lit_n = sun + view_dir
    lit_n /= np.linalg.norm(lit_n)
    dark_n = -sun + view_dir
    dark_n /= np.linalg.norm(dark_n)
    centre = np.array([1.3, 0, 1.5])
    lit = _lum(hdr, *_pixel(scene, centre + 0.9 * lit_n))
    dark = _lum(hdr, *_pixel(scene, centre + 0.9 * dark_n))
    assert lit > 2.5 * dark, (lit, dark)


def _shadow_scene(**shadows) -> Scene:
    # Sun from the east at 30 deg: a 4 m tall box (2 m east-west, 6 m north-south) at the origin
    # throws a 6.9 m long, 6 m wide shadow to the west.
    return _scene({
        "camera": {"position": [0, -22, 9], "heading": 0, "pitch": -22, "fov_y": 55, "width": 128, "height": 72,
                   "exposure_ev": 14},
        "time": {"utc": "2026-06-15T10:00:00Z", "sun_override": {"elevation": 30, "azimuth": 90}},
        "ground": {"enabled": True, "level": 0.0, "color": [0.4, 0.4, 0.4]},
        "entities": [{"id": "box", "model": "box", "position": [0, 0, 0], "scale": [2, 6, 4]}],
        "shadows": shadows,
    })


def test_shadow_falls_where_the_geometry_puts_it(renderer):
    scene = _shadow_scene()
    renderer.render(scene)
    hdr = renderer.read_hdr()
    assert "sun" in renderer.graph.passes["surfaces"].last_shadow_passes
    west = _lum(hdr, *_pixel(scene, [-4.0, 0.0, 0.0]))   # 3 m beyond the box's west face: in shadow
    east = _lum(hdr, *_pixel(scene, [4.0, 0.0, 0.0]))    # mirrored, sunlit
    far_west = _lum(hdr, *_pixel(scene, [-4.0, -7.0, 0.0]))  # west but off the shadow's line: sunlit
    # Independent expectation: the shadowed ground keeps only the sky's light. The frame's own light
    # inputs give sky radiance L (cd/m^2, irradiance/pi) and sun illuminance E: the ratio of shadowed
    # to sunlit ground is L / (L + E sin(30 deg) / pi) for a diffuse ground.
    from igserver.render.frame import build_frame

    frame = build_frame(renderer.ctx, scene)
    sky = float(np.dot(LUMA, frame.light.sky_ambient))
    sun = float(np.dot(LUMA, frame.light.sun_illuminance)) * 0.5 / math.pi
    expected = sky / (sky + sun)
    assert west / east < expected + 0.1, (west, east, expected)
    assert west / east > 0.5 * expected, (west, east, expected)  # sky light still reaches the shadow
    assert far_west / east == pytest.approx(1.0, abs=0.1)  # no shadow where no geometry blocks the sun
    # switched off: the same spot is lit
    renderer.render(_shadow_scene(enabled=False))
    off = renderer.read_hdr()
    assert _lum(off, *_pixel(scene, [-4.0, 0.0, 0.0])) / east == pytest.approx(1.0, abs=0.1)


def test_no_casters_no_shadow_pass_and_spot_light_shadows(renderer):
    night = {"camera": {"position": [0, -20, 8], "pitch": -20, "width": 64, "height": 36, "exposure_ev": 2},
             "time": {"utc": "2026-01-15T22:00:00Z"}, "ground": {"enabled": True, "level": 0.0},
             "lights": [{"id": "search", "type": "spot", "position": [-8, -8, 8], "heading": 45, "pitch": -35,
                         "intensity": 1e5, "range": 100, "cone_inner": 10, "cone_outer": 16}]}
    renderer.render(_scene(night))
    assert renderer.graph.passes["surfaces"].last_shadow_passes == []  # nothing casts
    renderer.render(_scene({**night, "entities": [{"id": "b", "model": "box", "scale": [2, 2, 3]}]}))
    assert renderer.graph.passes["surfaces"].last_shadow_passes == ["spot"]  # moonless night: spot only


def test_32_lights_each_light_their_own_pool(renderer):
    lights = [{"id": f"l{i}", "position": [-21.0 + 6.0 * (i % 8), -9.0 + 6.0 * (i // 8), 1.5],
               "intensity": 200.0, "range": 2.9, "color": [1.0, 0.9, 0.7]} for i in range(32)]
    scene = _scene({
        "camera": {"position": [0, 0, 30], "pitch": -90, "fov_y": 60, "width": 160, "height": 90, "exposure_ev": 3},
        "time": {"utc": "2026-01-15T22:00:00Z"},
        "ground": {"enabled": True, "level": 0.0},
        "lights": lights,
    })
    assert MAX_LIGHTS >= 32 and len(gather_lights(scene, make_view(scene.camera), MAX_LIGHTS)) == 32
    renderer.render(scene)
    hdr = renderer.read_hdr()
    for light in lights:
        x, y, _ = light["position"]
        under = _lum(hdr, *_pixel(scene, [x, y, 0.0]))
        between = _lum(hdr, *_pixel(scene, [x + 3.0, y + 3.0, 0.0]))  # 4.2 m away: beyond the 2.9 m range
        # 200 cd at 1.5 m: ~90 lux under each light against a moonless night's ~1e-3 lux
        assert under > 20.0 * max(between, 1e-9), (light["id"], under, between)


def test_parts_turn_and_hidden_entities_vanish(renderer):
    cam = {"position": [0.0, -22.0, 12.0], "heading": 0, "pitch": 3, "fov_y": 20, "width": 96, "height": 54,
           "exposure_ev": 14}
    # shadows off: a turning radar also moves its shadow; here only the part itself may change
    base = {"camera": cam, "time": {"utc": "2026-06-15T10:00:00Z"}, "ground": {"enabled": True, "level": 0.0},
            "shadows": {"enabled": False}}

    def frame(**entity):
        renderer.render(_scene({**base, "entities": [{"id": "boat", "model": "patrol_boat", "position": [0, 0, 1.8],
                                                      **entity}]}))
        return renderer.read_hdr()

    rest, turned = frame(parts={"radar": {"heading": 0}}), frame(parts={"radar": {"heading": 90}})
    changed = np.any(np.abs(rest - turned) > 1e-3, axis=-1)
    rows, cols = np.nonzero(changed)
    assert len(rows) > 0
    # the change is where the radar is (mast top: 3 m forward, 13.2 m above the entity), not elsewhere
    row, col = _pixel(_scene({**base}), [0.0, 3.0, 1.8 + 13.2])
    assert np.max(np.abs(rows - row)) < 12 and np.max(np.abs(cols - col)) < 20
    hidden = frame(visible=False)
    renderer.render(_scene(base))
    np.testing.assert_array_equal(hidden, renderer.read_hdr())


def test_key_light_map_does_not_move_with_the_camera():
    """Texel stability: the world -> shadow-map transform must not change when only the camera moves
    (the fit depends on the casters; the camera offset is folded in exactly)."""
    from igserver.render.surfaces.shadow_fit import fit_directional

    centers = np.array([[10.0, 20.0, 3.0], [-40.0, 5.0, 1.0], [1e6 + 3.0, 2.0, 0.0]])[:2]
    radii = np.array([5.0, 20.0])
    sun = np.array([0.3, -0.5, 0.81])
    sun /= np.linalg.norm(sun)
    world_maps = []
    for camera in ([0.0, -50.0, 5.0], [13.7, -41.2, 8.3], [-250.0, 300.0, 50.0]):
        fit = fit_directional(centers, radii, sun, np.array(camera), 1024)
        to_relative = np.eye(4)
        to_relative[:3, 3] = -np.asarray(camera)
        world_maps.append(fit.map_matrix() @ to_relative)
    for m in world_maps[1:]:
        np.testing.assert_allclose(m, world_maps[0], rtol=0, atol=1e-9)


def test_grazing_sun_has_neither_acne_nor_peter_panning(renderer):
    # Sun 8 deg above the horizon from the east: the box's shadow is 28 m long; the open ground
    # (lit) must be uniformly lit (no self-shadowing acne) and the shadow must start at the box's
    # foot (no gap: peter-panning).
    scene = _scene({
        "camera": {"position": [-12, -20, 6], "heading": 20, "pitch": -14, "fov_y": 60, "width": 128, "height": 72,
                   "exposure_ev": 12},
        "time": {"utc": "2026-06-15T10:00:00Z", "sun_override": {"elevation": 8, "azimuth": 90}},
        "ground": {"enabled": True, "level": 0.0, "color": [0.4, 0.4, 0.4]},
        "entities": [{"id": "box", "model": "box", "position": [0, 0, 0], "scale": [2, 6, 4]}],
    })
    from igserver.render.frame import build_frame

    frame = build_frame(renderer.ctx, scene)
    sky = float(np.dot(LUMA, frame.light.sky_ambient))
    sun = float(np.dot(LUMA, frame.light.sun_illuminance)) * math.sin(math.radians(8)) / math.pi
    expected = sky / (sky + sun)  # shadowed / lit diffuse ground, from the frame's light inputs
    renderer.render(scene)
    hdr = renderer.read_hdr()
    open_ground = [_lum(hdr, *_pixel(scene, [x, y, 0.0]), r=0) for x in (-10.0, -4.0, 2.0, 6.0) for y in (-9.0, -7.0)]
    # no acne: no sample of the open ground is even half as dark as the shadow (view-angle and
    # aerial-perspective differences between the samples are a few per cent)
    assert min(open_ground) > (expected + 0.5 * (1.0 - expected)) * max(open_ground), (open_ground, expected)
    lit = float(np.mean(open_ground))
    foot = _lum(hdr, *_pixel(scene, [-1.3, 0.0, 0.0]), r=0)   # 0.3 m west of the box's west face
    far = _lum(hdr, *_pixel(scene, [-8.0, 0.0, 0.0]), r=0)    # well inside the shadow
    assert far / lit < expected + 0.05, (far, lit, expected)
    # the shadow reaches the foot of the box: as dark there as far inside (5 % of the contrast)
    assert foot / lit < expected + 0.05 * (1.0 - expected) + 0.05, (foot, lit, expected)


def test_shadow_map_is_reused_only_while_nothing_changed(renderer):
    surfaces = renderer.graph.passes["surfaces"]
    scene = _shadow_scene()
    first = renderer.render(scene).rgba
    reused = surfaces.shadow_maps_reused
    again = renderer.render(scene).rgba
    assert surfaces.shadow_maps_reused == reused + 1  # same sun, casters, camera: not redrawn
    assert np.array_equal(first, again)
    # A moved caster redraws the map (its shadow moves): the frame equals one with the map forced
    # to be drawn again.
    moved = scene.model_copy(deep=True)
    moved.entities[0].position = [0.0, 2.0, 0.0]
    out = renderer.render(moved).rgba
    assert surfaces.shadow_maps_reused == reused + 1
    assert not np.array_equal(out, first)
    surfaces._shadow_signatures.clear()
    assert np.array_equal(renderer.render(moved).rgba, out)


@pytest.mark.parametrize("view", [{}, {"camera": {"pitch": -20.0}}, {"camera": {"position": [4.0, 10.0, 30.0], "pitch": -35.0}}])
def test_ground_drawn_with_the_shadow_lookup_only_under_the_casters_footprints(renderer, view, monkeypatch):
    # The snow scene's boxes on a clear day, sun 20 deg up: the ground is drawn without the key map's
    # lookup, then again with it inside each caster's shadow footprint (shadow_footprints.ground_shadow_rects:
    # its bounding sphere grown by the lookup's reach, swept along the light onto the ground). Every
    # shadowed pixel must lie in a footprint: the frame is the same as the ground drawn with the
    # lookup everywhere (the shadows: up to ~100 levels on 200-1200 pixels of these views).
    from igserver.render.surfaces import surfaces
    from igserver.scene import apply_patch, load_scene

    clear = {"camera": {"width": 320, "height": 180}, "weather": {"precipitation": {"type": "none"}},
             "atmosphere": {"visibility": 30000.0}, "time": {"sun_override": {"elevation": 20.0, "azimuth": 140.0}}}
    scene = apply_patch(apply_patch(load_scene("snow"), clear), view)
    split = renderer.render(scene).rgba
    assert renderer.graph.passes["surfaces"].ground_parts > 1
    monkeypatch.setattr(surfaces, "GROUND_SPLIT_MAX_AREA", 0.0)
    whole = renderer.render(scene).rgba
    assert renderer.graph.passes["surfaces"].ground_parts == 1
    np.testing.assert_array_equal(split, whole)
    lit = renderer.render(apply_patch(scene, {"shadows": {"enabled": False}})).rgba
    assert np.abs(lit.astype(int) - whole.astype(int)).max() > 20  # there are shadows on the ground


def test_ground_shadow_footprints_give_up_for_a_grazing_light():
    # Within 2 deg of the horizon a shadow runs to the horizon: no footprint rectangles.
    from igserver.render.surfaces.shadow_footprints import ground_shadow_rects
    from igserver.scene import load_scene

    view = make_view(load_scene("snow").camera)
    bounds = np.array([[8.0, 30.0, 1.3, 5.2]])
    low = np.array([0.0, -math.cos(math.radians(1.0)), math.sin(math.radians(1.0))])
    high = np.array([0.0, -math.cos(math.radians(30.0)), math.sin(math.radians(30.0))])
    assert ground_shadow_rects(bounds, low, 0.0, 0.5, view, (640, 360)) is None
    rects = ground_shadow_rects(bounds, high, 0.0, 0.5, view, (640, 360))
    assert rects is not None and len(rects) == 1 and rects[0][2] * rects[0][3] < 0.5 * 640 * 360


def _box_scene(sun_azimuth: float | None = None, light: dict | None = None) -> Scene:
    """A grey dielectric 2 m box at the origin, seen face-on from the south (its -y face)."""
    data = {"camera": {"position": [0.0, -8.0, 1.0], "heading": 0.0, "pitch": 0.0, "fov_y": 40.0,
                       "width": 64, "height": 36, "exposure_ev": 12.0 if light is None else 2.0},
            "ground": {"enabled": True, "level": 0.0},
            "shadows": {"enabled": False},
            "entities": [{"id": "b", "model": "box", "scale": [2.0, 2.0, 2.0], "color": [0.5, 0.5, 0.5],
                          "metallic": 0.0, "roughness": 0.9}]}
    if sun_azimuth is not None:
        data["time"] = {"sun_override": {"elevation": 30.0, "azimuth": sun_azimuth}}
    else:
        data["time"] = {"utc": "2026-01-15T22:00:00Z"}  # moonless night
        data["lights"] = [light]
    return _scene(data)


def test_builtin_box_is_lit_like_any_model(renderer):
    # The box's south face (normal -y) under a sun 30 deg up in the south (azimuth 180: the sun's
    # direction is (0, -cos 30, sin 30), cos i = cos 30) against the same sun in the north (the
    # face in its own shade). Reference: the Lambert term of the one BRDF, L = rho/pi E cos i, with
    # E the frame's own sun illuminance; tolerance: the face also gets sky and ground light (adds at
    # most the sky's irradiance, bounded above by pi L_sky) and a roughness-0.9 GGX lobe plus
    # Fresnel (F0 = 0.04) takes up to ~10 % of the diffuse at this view: lower bound 0.8 x.
    from igserver.render.frame import build_frame

    lit_scene = _box_scene(180.0)
    renderer.render(lit_scene)
    lit = _lum(renderer.read_hdr(), *_pixel(lit_scene, [0.0, -1.0, 1.0]))
    shade_scene = _box_scene(0.0)
    renderer.render(shade_scene)
    shade = _lum(renderer.read_hdr(), *_pixel(shade_scene, [0.0, -1.0, 1.0]))
    frame = build_frame(renderer.ctx, lit_scene)
    e_sun = float(LUMA @ frame.light.sun_illuminance)
    l_sky = float(LUMA @ frame.light.sky_ambient)
    direct = 0.5 / math.pi * e_sun * math.cos(math.radians(30.0)) * frame.exposure
    upper = direct + 0.5 * (l_sky + 0.1 * e_sun / math.pi) * frame.exposure  # sky + ground bounce
    assert 0.8 * direct < lit < 1.2 * upper, (lit, direct, upper)
    assert lit > 3.0 * shade, (lit, shade)
    # At night: a 2000 cd lamp 4 m in front of the face at its centre height, on the camera's side
    # of it: E = I / d^2 = 125 lx on the face, L = rho/pi E = 19.9 cd/m^2 (inverse square; the lamp's
    # range is far beyond); a lamp behind the box leaves the face dark.
    front = _box_scene(light={"id": "lamp", "position": [0.0, -5.0, 1.0], "intensity": 2000.0,
                              "color": [1.0, 1.0, 1.0], "range": 50.0})
    renderer.render(front)
    lamp_lit = _lum(renderer.read_hdr(), *_pixel(front, [0.0, -1.0, 1.0]))
    behind = _box_scene(light={"id": "lamp", "position": [0.0, 5.0, 1.0], "intensity": 2000.0,
                               "color": [1.0, 1.0, 1.0], "range": 50.0})
    renderer.render(behind)
    dark = _lum(renderer.read_hdr(), *_pixel(behind, [0.0, -1.0, 1.0]))
    expected = 0.5 / math.pi * 2000.0 / 16.0 * build_frame(renderer.ctx, front).exposure
    assert 0.8 * expected < lamp_lit < 1.25 * expected, (lamp_lit, expected)
    assert lamp_lit > 20.0 * dark, (lamp_lit, dark)
