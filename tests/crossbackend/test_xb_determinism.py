"""Same scene, same seed, same backend: the result is identical (the `identical` tier), so golden images
and cross-checks are reproducible; a different seed changes a path tracer's noise but not its geometry."""

from __future__ import annotations

import blendify_core as bf
from blendify_core.testing import marker_scene


def render(backend: str, seed: int) -> bf.RenderResult:
    scene, _ = marker_scene(resolution=(48, 36), fx=45.0, center=(24.2, 17.9), radius=0.3)
    return bf.render(scene, backend=backend, samples=8, seed=seed, outputs=("rgb", "depth", "normal", "instance"))


def test_same_seed_identical(backend):
    rep = bf.compare(render(backend, 3), render(backend, 3), tier="identical")
    print(rep)
    assert rep.passed, rep.summary()


def test_other_seed_same_geometry(path_tracer):
    a, b = render(path_tracer, 3), render(path_tracer, 4)
    assert not bf.compare(a, b, tier="identical", outputs=("rgb",)).passed, "the seed does not change the noise"
    rep = bf.compare(a, b, tier="geometry")
    assert rep.passed, rep.summary()
