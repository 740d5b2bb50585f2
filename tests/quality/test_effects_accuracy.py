"""Effect-aware settings (``effects=True``) give the same image as full settings (``effects=False``) within
noise: K independent renders of each, compared with the two-sample Welch test of blendify_core.evaluate.stats.
The time each side took is printed (the committed numbers are in benchmarks/results/accuracy_vs_time.md)."""

from __future__ import annotations

import time

import numpy as np
import pytest

import blendify_core as bf
from blendify_core.evaluate.stats import estimate_reference
from blendify_core.testing import bunny_scene, look_at_camera, pointcloud_scene

RES = 32
K = 8
SPP = 256


def _floor(s: bf.Scene) -> None:
    s.renderables.add_plane_mesh(4.0, bf.DiffuseMaterial(), bf.UniformColors((0.6, 0.6, 0.6)), tag="floor")


def _lit(s: bf.Scene) -> bf.Scene:
    look_at_camera(s, (RES, RES), (1.2, -1.2, 0.9), (0, 0, 0.25), fov_x=np.deg2rad(40))
    s.lights.add_sun(3.0, rotation_mode="eulerXYZ", rotation=(30, 20, 0))
    s.lights.set_background_light(0.3)
    return s


def lone_sphere() -> bf.Scene:
    """One convex diffuse object: no indirect light, no glossy, no caustics (direct light only)."""
    s = bf.Scene()
    s.renderables.add_sphere_nurbs(0.3, bf.DiffuseMaterial(), bf.UniformColors((0.8, 0.5, 0.3)), tag="ball")
    return _lit(s)


def rough_metal_on_floor() -> bf.Scene:
    """A rough metal sphere on a diffuse floor: glossy and indirect on, caustics judged off."""
    s = bf.Scene()
    s.renderables.add_sphere_nurbs(
        0.3, bf.MetalMaterial(roughness=0.5), bf.UniformColors((0.9, 0.7, 0.3)), translation=(0, 0, 0.3), tag="ball"
    )
    _floor(s)
    return _lit(s)


def half_transparent_sphere() -> bf.Scene:
    """One convex sphere with alpha 0.5: the camera sees its back face through the front one."""
    s = bf.Scene()
    s.renderables.add_sphere_nurbs(0.3, bf.DiffuseMaterial(alpha=0.5), bf.UniformColors((0.8, 0.8, 0.8)), tag="ball")
    return _lit(s)


SCENES = {
    "lone_sphere": lone_sphere,
    "bunny": lambda: bunny_scene((RES, RES)),
    "rough_metal": rough_metal_on_floor,
    "transparent_sphere": half_transparent_sphere,
    "pointcloud": lambda: pointcloud_scene(300, (RES, RES), point_size=0.08),
}


def _estimate(scene: bf.Scene, backend: str, effects: bool, seed0: int) -> tuple[object, float]:
    t0 = time.perf_counter()
    est = estimate_reference(scene, k=K, samples=SPP, seed0=seed0, backend=backend, effects=effects, threads=2)
    return est, time.perf_counter() - t0


def _check(scene_name: str, backend: str) -> None:
    scene = SCENES[scene_name]()
    bf.render(scene, backend=backend, samples=1)  # warm-up
    full, t_full = _estimate(scene, backend, False, 1000)
    eff, t_eff = _estimate(scene, backend, True, 5000)
    res = full.compare(eff)
    print(
        f"\n{backend} {scene_name}: full {t_full:.2f} s, effects {t_eff:.2f} s "
        f"(saved {100 * (1 - t_eff / t_full):.0f} %), Welch test passed={res.passed} "
        f"global p={res.global_p:.3g}, rejected {res.n_reject}/{res.n_tests}"
    )
    assert res.passed, f"{backend} {scene_name}: effect-aware image differs from full settings: {res.reasons}"


@pytest.mark.cycles
@pytest.mark.parametrize("scene_name", ["lone_sphere", "bunny", "rough_metal"])
def test_cycles_effects_cost_no_accuracy(cycles, scene_name):
    _check(scene_name, "cycles")


@pytest.mark.mitsuba
@pytest.mark.parametrize("scene_name", ["lone_sphere", "bunny", "rough_metal"])
def test_mitsuba_effects_cost_no_accuracy(mitsuba, scene_name):
    _check(scene_name, "mitsuba")


@pytest.mark.slow
@pytest.mark.parametrize("backend", ["cycles", "mitsuba"])
@pytest.mark.parametrize("scene_name", ["transparent_sphere", "pointcloud"])
def test_effects_cost_no_accuracy_more_scenes(request, backend, scene_name):
    request.getfixturevalue(backend)
    _check(scene_name, backend)
