"""Indirect light in the preview: one light probe (blendify_pyrender.probe) rendered from the scene replaces the
world's light for the diffuse term. Tiny renders."""

from __future__ import annotations

import numpy as np
import pytest

from blendify_core import DiffuseMaterial, PrincipledBSDFMaterial, Scene, UniformColors, render

pytestmark = pytest.mark.pyrender

ALBEDO = 0.6
SUN = 3.0


def _between_planes() -> Scene:
    """A floor lit by a sun through a ceiling 1 m above it that casts no shadow (both 12 m wide, albedo 0.6) and
    a small box between them; the camera between them looks straight up at the ceiling's underside, which no
    light reaches directly."""
    scene = Scene()
    grey = UniformColors((ALBEDO,) * 3, color_space="linear")
    scene.renderables.add_plane_mesh(12.0, DiffuseMaterial(), grey, tag="floor")
    ceiling = scene.renderables.add_plane_mesh(12.0, DiffuseMaterial(), grey, translation=(0, 0, 1.0), tag="ceiling")
    ceiling.emit_shadows = False
    # a small box off to the side: the probe is rendered from its centre (only flat objects: no probe)
    scene.renderables.add_cube_mesh(0.2, DiffuseMaterial(), grey, translation=(3.0, 3.0, 0.5), tag="box")
    scene.lights.add_sun(SUN, rotation_mode="eulerXYZ", rotation=(0, 0, 0))
    scene.set_perspective_camera((16, 16), fov_x=np.deg2rad(30), translation=(0, 0, 0.2), rotation=(0, 1, 0, 0))
    return scene


def test_light_bounces_off_the_floor_onto_the_ceiling(pyr, monkeypatch):
    from blendify_pyrender import render as rmod

    res = render(_between_planes(), backend=pyr, quality="preview")
    ceiling = float(res.rgba[..., :3].mean())
    # one bounce between large parallel planes: the ceiling sees the lit floor (radiance rho E / pi) over most
    # of its hemisphere: radiance up to rho^2 E / pi
    bound = ALBEDO**2 * SUN / np.pi
    print(f"ceiling {ceiling:.4f}, one-bounce bound {bound:.4f}")
    assert 0.6 * bound <= ceiling <= 1.05 * bound
    assert any(a.startswith("indirect light: ") for a in res.meta["approximations"])
    monkeypatch.setattr(rmod, "PROBE", False)
    dark = render(_between_planes(), backend=pyr, quality="preview")
    assert float(dark.rgba[..., :3].max()) < 0.01  # without the probe: no light reaches it


def test_probe_math():
    from blendify_pyrender.probe import cube_directions, probe_point, world_radiance
    from blendify_pyrender.translate import sh_basis, uniform_sh

    dirs, d_omega = cube_directions(8)
    assert 6 * d_omega.sum() == pytest.approx(4 * np.pi, rel=1e-3)
    assert all(np.allclose(np.linalg.norm(d, axis=1), 1.0) for d in dirs)
    # a uniform world projected from the cube's texels gives back its coefficients
    sh = uniform_sh(np.array([0.2, 0.5, 1.0]))
    acc = sum((sh_basis(d) * d_omega[:, None]).T @ world_radiance(sh, d) for d in dirs)
    band = np.array([1.0, 2 / 3, 2 / 3, 2 / 3, 0.25, 0.25, 0.25, 0.25, 0.25])
    assert np.allclose(acc * band[:, None], sh, atol=1e-3)
    # the point: the centre of the solid objects' bounds; objects holding it are hidden from the probe
    floor = ("floor", np.array([-5.0, -5, 0]), np.array([5.0, 5, 0]))
    ball = ("ball", np.array([-1.0, -1, 0]), np.array([1.0, 1, 2]))
    box = ("box", np.array([2.0, 2, 0]), np.array([3.0, 3, 1]))
    point, hidden = probe_point([floor, ball, box], diagonal=14.0)
    assert np.allclose(point, [1.0, 1.0, 1.0])
    assert hidden == ["ball"]
    _, hidden = probe_point([floor, ("wall", np.array([-5.0, 5, 0]), np.array([5.0, 5, 3]))], diagonal=14.0)
    assert hidden == ["floor", "wall"]  # only flat objects: no probe


def test_emission_is_left_out_of_the_probe(pyr):
    """The probe renders with emission off (emitters light the scene as lights already): the emissive panel's
    own glow does not light the scene twice."""
    scene = Scene()
    scene.set_orthographic_camera((8, 8), ortho_scale=1.0, translation=(0, 0, 3.0))
    scene.renderables.add_plane_mesh(
        1.0, PrincipledBSDFMaterial(emission_color=(1, 1, 1), emission_strength=0.5), UniformColors((0, 0, 0))
    )
    lit = render(scene, backend=pyr, quality="preview").rgba[..., :3].mean()
    assert lit == pytest.approx(0.5, rel=0.05)
    engine = pyr.engine_instance
    engine.renderer.emission_scale = 0.0
    try:
        dark = render(scene, backend=pyr, quality="preview").rgba[..., :3].mean()
    finally:
        engine.renderer.emission_scale = 1.0
    assert dark < 0.01


def test_cube_to_equirect_map():
    from blendify_pyrender.probe import equirect_from_cube

    n = 4
    faces = [np.full((n * n, 3), float(k)) for k in range(6)]  # faces +X, -X, +Y, -Y, +Z, -Z
    m = equirect_from_cube(faces, n, 8)  # (8, 16): row 0 at +Z, columns from azimuth -pi
    assert m.shape == (8, 16, 3)
    assert m[0, 0, 0] == 4 and m[-1, 0, 0] == 5  # the poles
    row = 3  # near the horizon
    azimuth = (np.arange(16) + 0.5) / 16 * 2 * np.pi - np.pi
    col = {0.0: 0, np.pi / 2: 2, -np.pi / 2: 3}  # +X, +Y, -Y
    for az, face in col.items():
        assert m[row, int(np.argmin(np.abs(azimuth - az))), 0] == face
    assert m[row, 0, 0] == 1  # azimuth -pi: -X


def test_metal_reflects_the_scene_around_it(pyr):
    """A mirror-like metal ball on a bright floor under a dark sky: its lower half reflects the floor (the probe,
    rendered from inside the ball, sees it), its upper half the sky."""
    scene = Scene()
    scene.set_orthographic_camera(
        (32, 32), ortho_scale=2.4, translation=(0, -5.0, 1.0), rotation=(0.7071068, 0.7071068, 0, 0)
    )
    scene.renderables.add_plane_mesh(20.0, DiffuseMaterial(), UniformColors((0.8, 0.8, 0.8), color_space="linear"))
    ball = scene.renderables.add_sphere_nurbs(
        1.0,
        PrincipledBSDFMaterial(metallic=1.0, roughness=0.1),
        UniformColors((0.9, 0.9, 0.9)),
        translation=(0, 0, 1.0),
    )
    ball.emit_shadows = False  # the floor it reflects is lit everywhere
    scene.lights.add_sun(3.0, rotation_mode="eulerXYZ", rotation=(0, 0, 0))
    scene.lights.set_background_light(0.05)
    res = render(scene, backend=pyr, quality="preview", outputs=("rgb", "instance"))
    rows = np.nonzero((res.instance == 1).any(axis=1))[0]
    top, bottom = rows.min(), rows.max()
    # medians: the sun's highlight (two pixels of radiance ~4 in the float colour pass) is not the sky's reflection
    upper = np.median(res.rgba[top + 3 : top + 8, 14:18, :3])
    lower = np.median(res.rgba[bottom - 7 : bottom - 2, 14:18, :3])
    print(f"upper {upper:.3f}, lower {lower:.3f}")
    assert lower > 2.0 * upper  # the world alone (0.05 everywhere) would leave the lower half dark
    # the probe's view keeps the hidden ball's shadow: the floor right under it is dark, and so is its reflection
    ball.emit_shadows = True
    shadowed = np.median(render(scene, backend=pyr, quality="preview").rgba[bottom - 7 : bottom - 2, 14:18, :3])
    assert shadowed < 0.5 * lower


def test_probe_grid_layout():
    from blendify_pyrender.probe import probe_grid

    # a room (flat walls 2 m apart) holding two boxes: a 3 x 3 x 3 grid inside the room, one probe per cell centre
    walls = [
        ("floor", np.array([-1.0, -1, -1]), np.array([1.0, 1, -1]), 2),
        ("ceiling", np.array([-1.0, -1, 1]), np.array([1.0, 1, 1]), 2),
        ("back", np.array([-1.0, 1, -1]), np.array([1.0, 1, 1]), 2),
    ]
    boxes = [
        ("tall", np.array([-0.6, -0.2, -1.0]), np.array([-0.1, 0.3, 0.2]), 12),
        ("short", np.array([0.1, -0.6, -1.0]), np.array([0.6, -0.1, -0.4]), 12),
    ]
    lo, hi, dims, points, hidden = probe_grid(walls + boxes, diagonal=3.5)
    assert dims == (3, 3, 3) and len(points) == 27
    assert np.all(lo >= -1.0) and np.all(hi <= 1.0)  # inside the room's bounds
    cell = (hi - lo) / 3
    assert np.allclose(points[0], lo + 0.5 * cell) and np.allclose(points[-1], hi - 0.5 * cell)
    for p, h in zip(points, hidden):  # a probe does not see the objects whose bounds hold it
        inside = [name for name, mn, mx, _ in boxes if np.all(p >= mn - 1e-2) and np.all(p <= mx + 1e-2)]
        assert set(inside) <= set(h)
    # too many triangles for 27 probes' renders: a coarser grid, then none (one probe)
    _, _, dims, _, _ = probe_grid([*walls, ("tall", *boxes[0][1:3], 12_000)], diagonal=3.5)
    assert dims != (3, 3, 3)
    assert probe_grid([*walls, ("tall", *boxes[0][1:3], 10**8)], diagonal=3.5) is None
    assert probe_grid(walls, diagonal=3.5) is None  # only flat objects


def _half_white_floor() -> Scene:
    """Between a ceiling (albedo 0.6, casting no shadow) and a floor 1 m below it, white (0.8) for x < 0 and black
    for x > 0, lit by a sun from straight above; two small boxes at x = -4 and 4 set the probes' extent. The
    camera looks straight up at the ceiling's underside from x = -5 to 5. (Boxes thinner than 1 % of the scene's
    diagonal would count as flat.)"""
    scene = Scene()
    scene.renderables.add_plane_mesh(
        6.0, DiffuseMaterial(), UniformColors((0.8,) * 3, color_space="linear"), translation=(-3.0, 0, 0)
    )
    scene.renderables.add_plane_mesh(
        6.0, DiffuseMaterial(), UniformColors((0.0,) * 3, color_space="linear"), translation=(3.0, 0, 0)
    )
    grey = UniformColors((ALBEDO,) * 3, color_space="linear")
    ceiling = scene.renderables.add_plane_mesh(12.0, DiffuseMaterial(), grey, translation=(0, 0, 1.0))
    ceiling.emit_shadows = False
    for x in (-4.0, 4.0):
        box = scene.renderables.add_cube_mesh(0.3, DiffuseMaterial(), grey, translation=(x, 0, 0.5))
        box.emit_shadows = False
    scene.lights.add_sun(SUN, rotation_mode="eulerXYZ", rotation=(0, 0, 0))
    scene.set_orthographic_camera((40, 8), ortho_scale=10.0, translation=(0, 0, 0.2), rotation=(0, 1, 0, 0))
    return scene


def test_grid_of_probes_lights_the_ceiling_above_the_lit_floor(pyr, monkeypatch):
    """The ceiling above the white half of the floor gets its bounce light (about rho_c rho_f E / pi), the ceiling
    above the black half almost none (the white half is 3 m away and more: a view factor under 0.05). One probe
    for the whole scene lights both alike."""
    from blendify_pyrender import probe

    res = render(_half_white_floor(), backend=pyr, quality="preview")
    rgb = res.rgba[..., :3].mean(axis=(0, 2))  # per column: x from -5 (left) to 5
    above_white, above_black = float(rgb[:3].mean()), float(rgb[-3:].mean())  # beside the boxes
    one_bounce = ALBEDO * 0.8 * SUN / np.pi
    print(f"ceiling above white {above_white:.4f}, above black {above_black:.4f}, one bounce {one_bounce:.4f}")
    assert any(a.startswith("indirect light: a grid of 3 x 1 x 1") for a in res.meta["approximations"])
    assert 0.6 * one_bounce <= above_white <= 1.3 * one_bounce
    assert above_black < 0.3 * above_white
    monkeypatch.setattr(probe, "GRID", 1)
    one = render(_half_white_floor(), backend=pyr, quality="preview").rgba[..., :3].mean(axis=(0, 2))
    assert float(one[-3:].mean()) > 0.7 * float(one[:3].mean())  # one probe: the same light everywhere
