"""Same geometry in every backend: depth and shading normals at pixel centres >= 2 px inside every
silhouette agree between all three backends (depth q99 <= 1e-4 relative, normal q99 <= 0.5 deg), on a
smooth mesh with n-gon caps (the IR's angle-weighted vertex normals passed to every engine)."""

from __future__ import annotations

import pytest
from xb_util import PAIRS, geometry_agreement, require

import blendify_core as bf
from blendify_core import testing

DEPTH_Q99 = 1e-4
NORMAL_Q99_DEG = 0.5


def _geometry(renders, key: str, backend: str, build) -> bf.RenderResult:
    return renders.get(key, backend, build, samples=4, outputs=("depth", "normal", "instance"))


@pytest.mark.parametrize("pair", PAIRS, ids=[f"{a}-{b}" for a, b in PAIRS])
def test_smooth_cylinder_with_ngon_caps(renders, pair):
    a, b = pair
    require(a)
    require(b)
    ra, rb = (_geometry(renders, "smooth-cylinder", x, testing.smooth_cylinder_scene) for x in pair)
    m = geometry_agreement(ra, rb)
    print(f"{a} vs {b}: {m}")
    assert m["pixels"] > 300
    assert m["depth_rel_q99"] <= DEPTH_Q99
    assert m["normal_deg_q99"] <= NORMAL_Q99_DEG
