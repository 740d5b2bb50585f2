"""UV orientation across backends: a quad with a 2x2 texture (top-left red, top-right green, bottom-left
blue, bottom-right white) under a uniform white background must show each texel in its own image quadrant
in every backend, with vertex and per-face UVs; pairwise colour agreement at the pair's tier."""

from __future__ import annotations

import numpy as np
import pytest

import blendify_core as bf
from blendify_core.compare import choose_tier
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
