"""Clouds of sub-pixel spheres in the preview: every sphere shaded once as a whole and splatted into the pixels it
covers (blendify_pyrender.render: FrameRenderer._shade_points, splat_points), against references computed here."""

from __future__ import annotations

import numpy as np
import pytest

from blendify_core import DiffuseMaterial, Scene, UniformColors, VertexColors, render

#: the orthographic test camera: 48 x 36 pixels of 0.05 world units, looking down -Z from z = 5
W, H, PX = 48, 36, 0.05


def _ortho_scene(pts: np.ndarray, d_px: float, colors=None) -> Scene:
    scene = Scene()
    scene.set_orthographic_camera((W, H), ortho_scale=W * PX, translation=(0, 0, 5.0), near=0.1, far=20)
    col = (
        UniformColors((0.8, 0.8, 0.8), color_space="linear")
        if colors is None
        else VertexColors(colors, color_space="linear")
    )
    scene.renderables.add_pointcloud(pts, DiffuseMaterial(), col, point_size=PX * d_px, tag="points")
    return scene


def _supersampled(pts: np.ndarray, d_px: float, colors: np.ndarray, k: int = 16) -> tuple[np.ndarray, np.ndarray]:
    """What a path tracer's box filter converges to for spheres in the plane z = 0 seen from +Z (the nearest
    sphere wins a sample): (H, W) coverage and (H, W, 3) mean of colour x covered, from k x k samples a pixel."""
    fine = np.full((H * k, W * k), -1, dtype=np.int64)
    best = np.full((H * k, W * k), -np.inf)
    u = (pts[:, 0] / PX + W / 2) * k  # fine-sample units, rows top to bottom
    v = (H / 2 - pts[:, 1] / PX) * k
    r = d_px / 2 * k
    span = int(np.ceil(r)) + 1
    for dy in range(-span, span + 1):
        for dx in range(-span, span + 1):
            cx = np.floor(u).astype(int) + dx
            cy = np.floor(v).astype(int) + dy
            inside = (cx + 0.5 - u) ** 2 + (cy + 0.5 - v) ** 2 <= r * r
            inside &= (cx >= 0) & (cx < W * k) & (cy >= 0) & (cy < H * k)
            i = np.nonzero(inside)[0]
            nearer = pts[i, 2] > best[cy[i], cx[i]]
            i = i[nearer]
            best[cy[i], cx[i]] = pts[i, 2]
            fine[cy[i], cx[i]] = i
    covered = fine >= 0
    rgb = np.where(covered[..., None], colors[np.maximum(fine, 0)], 0.0)
    cov = covered.reshape(H, k, W, k).mean(axis=(1, 3))
    return cov, rgb.reshape(H, k, W, k, 3).mean(axis=(1, 3))


@pytest.mark.parametrize("d_px", [0.15, 0.4])
def test_dense_sub_pixel_cloud_matches_the_supersampled_reference(pyr, d_px):
    """A dense cloud of sub-pixel spheres with colours varying across it, under uniform light: each pixel's
    coverage and colour follow the spheres that fall in it (a supersampled reference computed here), not the
    speckle of a thinned subset."""
    rng = np.random.default_rng(5)
    n = int(1.5 * W * H / d_px**2)  # 1.5 / d_px^2 spheres a pixel: 1.18 pixels of area, coverage ~0.7
    pts = np.c_[rng.uniform(-1.2, 1.2, n), rng.uniform(-0.9, 0.9, n), rng.uniform(-1e-3, 1e-3, n)]
    colors = np.c_[0.2 + 0.6 * (pts[:, 0] + 1.2) / 2.4, 0.8 - 0.6 * (pts[:, 1] + 0.9) / 1.8, np.full(n, 0.3)]
    scene = _ortho_scene(pts, d_px, colors)
    scene.lights.set_background_light(1.0)
    render(scene, backend=pyr, quality="preview")
    res = render(scene, backend=pyr, quality="preview")  # a later frame (the first one uploads the cloud)
    cov, rgb = _supersampled(pts, d_px, colors)
    alpha = res.rgba[..., 3]
    assert 0.1 < cov.mean() < 0.9
    # coverage pixel by pixel (the reference's own sampling noise: k = 16 samples a pixel side)
    # (the thinned spheres of the blended colour pass: 0.2; splatted 0.02 at 0.15 px, 0.05 at 0.4 px: the square
    # footprint and the independent spheres' coverage against the discs' union)
    assert np.abs(alpha - cov).mean() < 0.07, np.abs(alpha - cov).mean()
    assert abs(alpha.mean() - cov.mean()) < 0.03 * cov.mean()
    # colour pixel by pixel: premultiplied radiance against the reference's colour x coverage (uniform light of
    # radiance 1: a diffuse sphere's radiance is its albedo), up to the preview's calibration of that light
    pre = res.rgba[..., :3]
    scale = float((pre * rgb).sum() / (rgb * rgb).sum())
    assert 0.85 < scale < 1.15, scale
    err = np.abs(pre / scale - rgb).mean(axis=-1)
    assert err.mean() < 0.04, err.mean()  # (thinned: 0.09; splatted: 0.01 at 0.15 px, 0.02 at 0.4 px)
    # chromaticity where there is something: the weighted mean colour, not one sphere's
    some = (cov > 0.1) & (alpha > 0.01)
    assert some.sum() > 0.9 * (cov > 0.1).sum()
    straight = pre[some] / alpha[some, None]
    expected = rgb[some] / cov[some, None]
    assert np.abs(straight / scale - expected).mean() < 0.04


@pytest.mark.parametrize("phase_deg", [0.0, 90.0, 150.0])
def test_sub_pixel_sphere_shows_a_lambertian_sphere_s_mean(pyr, phase_deg):
    """Each sub-pixel sphere is shaded as a whole: under a sun at phase angle a from the eye (seen along -Z), its
    radiance is the mean over the disc it shows, albedo E / pi x (2/3) (sin a + (pi - a) cos a) / pi (lit from the
    side it is a half-lit disc, from behind a crescent)."""
    rng = np.random.default_rng(2)
    n = 60
    pts = np.c_[rng.uniform(-1.0, 1.0, n), np.linspace(-0.8, 0.8, n), np.zeros(n)]  # no two share a sun ray
    scene = _ortho_scene(pts, 0.5)
    strength = 3.0
    # the sun shines along its local -Z; rotated about Y by the phase angle it leans toward +X
    scene.lights.add_sun(strength, rotation_mode="eulerXYZ", rotation=(0, phase_deg, 0))
    res = render(scene, backend=pyr, quality="preview")
    alpha = res.rgba[..., 3]
    some = alpha > 0.05
    radiance = np.median(res.rgba[..., :3][some] / alpha[some, None], axis=0)
    a = np.deg2rad(phase_deg)
    mean_nl = (2.0 / 3.0) * (np.sin(a) + (np.pi - a) * np.cos(a)) / np.pi
    expected = 0.8 * strength / np.pi * mean_nl
    np.testing.assert_allclose(radiance, expected, rtol=0.08, atol=0.002)


def test_splatted_spheres_hide_behind_an_opaque_surface(pyr):
    """Black spheres in front of and behind a white plane over the left half of the view: those behind it are
    hidden, so the plane shows through the coverage of the spheres in front of it (1 - exp(-their summed area per
    pixel)), and where there is no plane the film through the coverage of all of them."""
    rng = np.random.default_rng(7)
    n = 12000
    d_px = 0.4
    pts = np.c_[rng.uniform(-1.2, 1.2, n), rng.uniform(-0.9, 0.9, n), rng.uniform(-0.5, 0.5, n)]
    black = np.zeros((n, 3))

    def scene(with_cloud: bool) -> Scene:
        s = _ortho_scene(pts, d_px, black)
        if not with_cloud:
            s.renderables.remove("points")
        s.renderables.add_plane_mesh(
            1.2,
            DiffuseMaterial(),
            UniformColors((0.8, 0.8, 0.8), color_space="linear"),
            translation=(-0.6, 0, 0),
            tag="plane",
        )
        s.lights.set_background_light(1.0)
        return s

    res = render(scene(True), backend=pyr, quality="preview")
    bare = render(scene(False), backend=pyr, quality="preview", outputs=("rgb", "instance"))
    plane = bare.instance == bare.instance_tags.index("plane")
    # away from the plane's anti-aliased edge
    inner = plane & np.pad(plane[1:-1, 1:-1], 1) & np.roll(plane, 1, 0) & np.roll(plane, -1, 0)
    inner &= np.roll(plane, 1, 1) & np.roll(plane, -1, 1)
    empty = (bare.rgba[..., 3] == 0) & (np.arange(W)[None, :] >= W // 2 + 2)
    assert inner.sum() > 150 and empty.sum() > 200
    area = np.pi * d_px**2 / 4 / (W * H)  # one sphere's share of the image
    seen = res.rgba[..., :3].mean(axis=-1)[inner].mean() / bare.rgba[..., :3].mean(axis=-1)[inner].mean()
    assert abs(seen - np.exp(-n * area / 2)) < 0.05, (seen, np.exp(-n * area / 2))
    assert abs(res.rgba[..., 3][empty].mean() - (1 - np.exp(-n * area))) < 0.05


def test_splat_composites_depth_slabs_front_to_back():
    """splat_points itself: a red layer of spheres in front of a green one (perspective camera): a pixel shows
    the front layer's coverage a_f = 1 - exp(-A_f) in red and the back's through it, exp(-A_f) (1 - exp(-A_b)),
    in green, whatever the order of the spheres."""
    from blendify_pyrender.render import splat_points

    rng = np.random.default_rng(1)
    w, h, f = 40, 30, 40.0  # focal length in pixels
    proj = np.array([[2 * f / w, 0, 0, 0], [0, 2 * f / h, 0, 0], [0, 0, -1.002, -0.2002], [0, 0, -1, 0]])
    n = 20000
    depth = np.r_[np.full(n // 2, 4.0), np.full(n // 2, 6.0)]
    x = rng.uniform(-w / 2, w / 2, n) / f * depth  # uniform over the image at each depth
    y = rng.uniform(-h / 2, h / 2, n) / f * depth
    order = rng.permutation(n)
    centres = np.stack([x, y, -depth])[:, order]
    radii = np.full(n, 0.15 / f) * depth[order]  # 0.3 px at either depth
    radiance = np.where(depth[order] < 5, [[1.0], [0.0], [0.0]], [[0.0], [1.0], [0.0]])
    img = splat_points(centres, radii, radiance, np.ones(n), np.eye(4), proj, w, h)
    area = np.pi * 0.15**2 * (n // 2) / (w * h)
    front, back = 1 - np.exp(-area), np.exp(-area) * (1 - np.exp(-area))
    assert abs(img[..., 0].mean() - front) < 0.03 * front
    assert abs(img[..., 1].mean() - back) < 0.05 * back
    assert abs(img[..., 3].mean() - (1 - np.exp(-2 * area))) < 0.03
    # hidden behind a surface at depth 5 (window depth of the planar depth 5): only the front layer is left
    z_ndc = (-1.002 * -5.0 - 0.2002) / 5.0
    img = splat_points(centres, radii, radiance, np.ones(n), np.eye(4), proj, w, h, np.full((h, w), 0.5 * z_ndc + 0.5))
    assert img[..., 1].max() == 0.0 and abs(img[..., 0].mean() - front) < 0.03 * front


def test_splatted_spheres_take_every_light_group(pyr):
    """More lights than a pass binds (80 point lights: up to 64 a pass): the colour pass runs in light groups and
    each sphere's shade adds up over them (80 lights of P / 80 at one place light a cloud as one light of P)."""
    rng = np.random.default_rng(4)
    n = 400
    pts = np.c_[rng.uniform(-1.0, 1.0, n), rng.uniform(-0.8, 0.8, n), np.zeros(n)]

    def lit(count: int) -> np.ndarray:
        scene = _ortho_scene(pts, 0.5)
        for _ in range(count):
            scene.lights.add_point(200.0 / count, translation=(0.5, 0.2, 2.0))
        res = render(scene, backend=pyr, quality="preview")
        alpha = res.rgba[..., 3]
        return res.rgba[..., :3][alpha > 0.05].sum(axis=0) / alpha[alpha > 0.05].sum()

    one = lit(1)
    assert one.min() > 0.05
    np.testing.assert_allclose(lit(80), one, rtol=0.02)


def test_translucent_splatted_spheres_cover_by_their_opacity(pyr):
    """Spheres of opacity 0.5 (a colour's alpha) let half the light through: the cloud covers
    1 - exp(-0.5 x the summed area per pixel), as many independent half-transparent spheres do."""
    rng = np.random.default_rng(9)
    n, d_px = 8000, 0.3
    pts = np.c_[rng.uniform(-1.2, 1.2, n), rng.uniform(-0.9, 0.9, n), rng.uniform(-0.5, 0.5, n)]
    area = n * np.pi * d_px**2 / 4 / (W * H)
    for alpha in (1.0, 0.5):
        scene = Scene()
        scene.set_orthographic_camera((W, H), ortho_scale=W * PX, translation=(0, 0, 5.0), near=0.1, far=20)
        scene.renderables.add_pointcloud(
            pts, DiffuseMaterial(), UniformColors((0.8, 0.8, 0.8, alpha), color_space="linear"), point_size=PX * d_px
        )
        scene.lights.set_background_light(1.0)
        res = render(scene, backend=pyr, quality="preview")
        expected = 1 - np.exp(-alpha * area)
        assert abs(res.rgba[..., 3].mean() - expected) < 0.05 * expected, (alpha, res.rgba[..., 3].mean(), expected)


def test_splatted_spheres_take_shadows(pyr):
    """Shadows fall onto the splatted spheres: a square out of view, above the cloud, hides the sun (shining
    from -X, 45 deg) from the spheres left of x = 0.3; those to the right keep it."""
    rng = np.random.default_rng(11)
    n = 3000
    pts = np.c_[rng.uniform(-1.2, 1.2, n), rng.uniform(-0.9, 0.9, n), np.zeros(n)]
    scene = _ortho_scene(pts, 0.5)
    scene.renderables.add_plane_mesh(
        1.8, DiffuseMaterial(), UniformColors((0.5, 0.5, 0.5)), translation=(-2.1, 0, 1.5), tag="roof"
    )
    scene.lights.add_sun(3.0, rotation_mode="eulerXYZ", rotation=(0, -45, 0))
    res = render(scene, backend=pyr, quality="preview", outputs=("rgb", "instance"))
    assert not np.any(res.instance == res.instance_tags.index("roof"))  # out of view
    alpha = res.rgba[..., 3]
    x = (np.arange(W) + 0.5) * PX - W * PX / 2
    lum = np.where(alpha > 0.05, res.rgba[..., :3].mean(axis=-1) / np.maximum(alpha, 1e-6), np.nan)
    shaded = np.nanmedian(lum[:, x < -0.2])
    lit = np.nanmedian(lum[:, x > 0.7])
    a = np.deg2rad(45.0)
    expected = 0.8 * 3.0 / np.pi * (2.0 / 3.0) * (np.sin(a) + (np.pi - a) * np.cos(a)) / np.pi
    assert abs(lit - expected) < 0.1 * expected, (lit, expected)
    assert shaded < 0.05 * lit, (shaded, lit)
