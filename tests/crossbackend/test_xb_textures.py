"""UV orientation across backends: a quad with a 2x2 texture (top-left red, top-right green, bottom-left
blue, bottom-right white) under a uniform white background must show each texel in its own image quadrant
in every backend, with vertex and per-face UVs; pairwise colour agreement at the pair's tier."""

from __future__ import annotations

import numpy as np
import pytest

import blendify_core as bf
from blendify_core.evaluate.tiers import choose_tier
from blendify_core.testing import textured_quad_scene

# linear radiance of each quadrant: albedo x background radiance 1 (Lambertian under a uniform sky)
QUADRANTS = {
    "top-left": ((slice(4, 28), slice(4, 28)), (1.0, 0.0, 0.0)),
    "top-right": ((slice(4, 28), slice(36, 60)), (0.0, 1.0, 0.0)),
    "bottom-left": ((slice(36, 60), slice(4, 28)), (0.0, 0.0, 1.0)),
    "bottom-right": ((slice(36, 60), slice(36, 60)), (1.0, 1.0, 1.0)),
}


def render(renders, faces_uv: bool, backend: str) -> bf.RenderResult:
    key = f"textured-quad-{'faces' if faces_uv else 'vertex'}"
    try:
        return renders.get(
            key,
            backend,
            lambda: textured_quad_scene(faces_uv=faces_uv),
            samples=64,
            outputs=("rgb", "albedo", "depth", "instance"),
        )
    except bf.UnsupportedFeatureError as exc:
        print(f"SKIP: {exc}")
        pytest.skip(str(exc))


@pytest.mark.parametrize("faces_uv", [False, True], ids=["vertex_uv", "faces_uv"])
def test_texture_quadrants(renders, backend, faces_uv):
    result = render(renders, faces_uv, backend)
    for name, ((rows, cols), colour) in QUADRANTS.items():
        mean = result.rgb[rows, cols].reshape(-1, 3).mean(axis=0)
        print(f"{backend} {name}: {np.round(mean, 3).tolist()} (expected {colour})")
        # orientation: the texel's channels are bright and the others dark (a flipped V or U swaps quadrants)
        assert np.allclose(mean, colour, atol=0.1), f"{backend}: {name} quadrant is {mean}, expected {colour}"
        if result.albedo is not None:
            alb = result.albedo[rows, cols].reshape(-1, 3).mean(axis=0)
            assert np.allclose(alb, colour, atol=0.02), f"{backend}: {name} albedo {alb}, expected {colour}"


@pytest.mark.parametrize("faces_uv", [False, True], ids=["vertex_uv", "faces_uv"])
def test_texture_pairwise(renders, pair, faces_uv, artifacts_dir):
    a, b = pair
    ra, rb = render(renders, faces_uv, a), render(renders, faces_uv, b)
    rep = bf.compare(ra, rb, tier=choose_tier(a, b, textured_quad_scene()), names=pair)
    print(rep)
    if not rep.passed:
        rep.save(artifacts_dir)
    assert rep.passed, rep.summary()


def gradient_scene() -> bf.Scene:
    """A quad with a 2x1 texture (black, white), bilinear: the albedo profile across the image shows in
    which space each engine interpolates 8-bit sRGB textures."""
    scene = bf.Scene()
    tex = np.array([[[0, 0, 0], [255, 255, 255]]], dtype=np.uint8)
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], dtype=float)
    uv = bf.VertexUV(np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float))
    scene.renderables.add_mesh(
        v, np.array([[0, 1, 2, 3]]), bf.DiffuseMaterial(), bf.TextureColors(tex, uv, interpolation="linear"), tag="q"
    )
    scene.set_orthographic_camera((16, 4), ortho_scale=2.0, translation=(0, 0, 3.0))
    scene.lights.set_background_light(1.0)
    return scene


# All three interpolate 8-bit sRGB texels in encoded space, then decode (Blender's behaviour for byte
# images): half-way between a black and a white texel the albedo is 0.21, not 0.5. Mitsuba decoded first
# until this test caught it (fuze.obj came out 1-5 % brighter); it is a regression test now.


def test_texture_interpolation_space_pairwise(renders, pair):
    a, b = pair
    ra = renders.get("gradient", a, gradient_scene, samples=16, outputs=("rgb", "albedo"))
    rb = renders.get("gradient", b, gradient_scene, samples=16, outputs=("rgb", "albedo"))
    pa, pb = ra.albedo[2, :, 0], rb.albedo[2, :, 0]
    print(f"{a}: {np.round(pa, 3).tolist()}\n{b}: {np.round(pb, 3).tolist()}")
    assert np.allclose(pa, pb, atol=0.01), f"{a} vs {b}: texture interpolation profiles differ"
    mid = pa[8]  # image column 8 of 16: a quarter of the way from the white texel's centre to the black one's
    assert abs(mid - 0.2765) < 0.01, f"{a}: {mid} (sRGB-space interpolation gives 0.2765, linear 0.5625)"
