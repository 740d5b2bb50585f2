"""The statistical test on real path-traced renders: a render with a new seed is consistent with a K-render
reference of the same backend, a 5 % bias is not, and Cycles and Mitsuba are statistically consistent on
the area-light plane (two-sample test). Small: 32x32, 8-16 spp."""

from __future__ import annotations

import numpy as np
import pytest

import blendify_core as bf
from blendify_core.evaluate.stats import ReferenceEstimate, estimate_reference
from blendify_core.testing import plane_scene

K, SPP = 6, 8


def scene() -> bf.Scene:
    return plane_scene("area", resolution=(32, 32))


_refs: dict[str, ReferenceEstimate] = {}


def reference(backend: str) -> ReferenceEstimate:
    if backend not in _refs:
        _refs[backend] = estimate_reference(scene(), k=K, samples=SPP, backend=backend, seed0=100)
    return _refs[backend]


def test_new_seed_passes_bias_fails(path_tracer):
    ref = reference(path_tracer)
    # the seed must change the noise, or the variance estimate (and the test) is meaningless
    assert float(np.median(ref.var)) > 1e-6, f"{path_tracer}: renders with different seeds are identical"
    image = bf.render(scene(), backend=path_tracer, samples=SPP, seed=7, denoise=False, adaptive=False).rgb
    ok = ref.z_test(image)
    print(f"{path_tracer}: new seed {ok}")
    assert ok.passed, ok.reasons
    bad = ref.z_test(image * 1.05)
    print(f"{path_tracer}: x1.05 {bad}")
    assert not bad.passed


def test_cycles_mitsuba_statistically_consistent():
    for name in ("cycles", "mitsuba"):
        st = bf.available_backends().get(name)
        if st is None or not st.available:
            reason = f"backend {name!r} unavailable: {None if st is None else st.reason}"
            print(f"SKIP: {reason}")
            pytest.skip(reason)
    z = reference("cycles").compare(reference("mitsuba"))
    print(f"cycles vs mitsuba: {z}")
    assert z.passed, z.reasons
