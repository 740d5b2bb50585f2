"""A sun with an angular diameter in Mitsuba: a distant disk emitter (soft shadows as Cycles' sun), the same
irradiance as the delta sun, out of the camera's view, and a delta sun (listed) in scenes too large for it."""

from __future__ import annotations

import math

import numpy as np
import pytest
from blendify_mitsuba import MitsubaBackend
from blendify_mitsuba.translate import SUN_DISK_MAX_DISTANCE, SUN_DISK_MIN_DISTANCE, MitsubaTranslator

import blendify_core as bf
from blendify_core import testing
from blendify_core.pipeline.settings import resolve_settings

_status = MitsubaBackend.probe()
if not _status.available:  # pragma: no cover - depends on the machine
    print(f"\nskipping the mitsuba backend tests: {_status.reason}")
    pytest.skip(f"mitsuba backend unavailable: {_status.reason}", allow_module_level=True)

pytestmark = pytest.mark.mitsuba


def _plane_under_sun(angular_diameter: float, size: float = 4.0, occluder: bool = True) -> bf.Scene:
    s = bf.Scene()
    s.renderables.add_plane_mesh(size, bf.DiffuseMaterial(), bf.UniformColors((0.8, 0.8, 0.8)), tag="ground")
    if occluder:
        s.renderables.add_cube_mesh(
            0.15 * size, bf.DiffuseMaterial(), bf.UniformColors((0.8, 0.2, 0.2)), translation=(0, 0, 0.2 * size)
        )
    testing.look_at_camera(s, (48, 36), (0.0, -0.01 * size, size), (0, 0, 0), fov_x=np.deg2rad(40))
    s.camera.far = 10 * size
    s.lights.add_sun(3.0, angular_diameter=angular_diameter, rotation_mode="eulerXYZ", rotation=(20, 0, 0))
    return s


def test_sun_disk_radiance_gives_the_irradiance(mi_scalar):
    scene = _plane_under_sun(np.deg2rad(5.0))
    tr = MitsubaTranslator(resolve_settings(samples=4)).translate(scene)
    disk = tr.scene_dict["light0000"]
    assert disk["type"] == "disk" and disk["emitter"]["type"] == "area"
    m = np.array(disk["to_world"].matrix, dtype=np.float64)
    centre, normal = m[:3, 3], m[:3, 2] / np.linalg.norm(m[:3, 2])
    radius = float(np.linalg.norm(m[:3, 0]))
    dist = float(np.linalg.norm(centre))
    np.testing.assert_allclose(normal, next(iter(scene.lights)).direction, atol=1e-6)  # emits towards the scene
    assert math.degrees(2 * math.atan(radius / dist)) == pytest.approx(5.0, rel=1e-3)
    radiance = disk["emitter"]["radiance"]["value"][0]
    sin2 = radius**2 / (radius**2 + dist**2)
    assert radiance * math.pi * sin2 == pytest.approx(3.0, rel=1e-3)  # irradiance on a surface facing it


def test_soft_sun_same_light_as_the_delta_sun_and_out_of_view():
    """An unshadowed plane: the disk's light equals the delta sun's; the camera looking straight at the sun
    sees nothing there (a null surface, as Cycles' sun is invisible to the camera), also with an opaque film
    and a far clip beyond the disk."""
    soft = bf.render(_plane_under_sun(np.deg2rad(5.0), occluder=False), "mitsuba", samples=64)
    hard = bf.render(_plane_under_sun(0.0, occluder=False), "mitsuba", samples=64)
    assert soft.rgba[..., :3].mean() / hard.rgba[..., :3].mean() == pytest.approx(1.0, abs=2e-3)
    assert not any("light.sun.soft" in a for a in soft.meta["approximations"])
    s = bf.Scene()
    s.renderables.add_plane_mesh(1.0, bf.DiffuseMaterial(), bf.UniformColors((0.8, 0.8, 0.8)), translation=(3, 0, 3))
    s.lights.add_sun(3.0, angular_diameter=np.deg2rad(20.0))  # shines down -Z: the sun is straight up
    testing.look_at_camera(s, (16, 16), (0, 0, 0), (0, 0.001, 1), fov_x=np.deg2rad(60))
    s.camera.far = 1e5  # beyond the disk
    up = bf.render(s, "mitsuba", samples=4, outputs=("rgb",), transparent_background=False)
    assert float(up.rgba[..., :3].max()) == 0.0


def test_soft_sun_penumbra_widens_with_the_angle():
    """The shadow's penumbra: absent for the delta sun, growing with the angular diameter."""

    def penumbra(angle: float) -> int:
        r = bf.render(_plane_under_sun(np.deg2rad(angle)), "mitsuba", samples=128, outputs=("rgb", "instance"))
        g = r.rgba[..., :3].mean(-1)[r.instance == 0]
        lit = np.percentile(g, 90)
        return int(((g > 0.1 * lit) & (g < 0.9 * lit)).sum())

    hard, soft, softer = penumbra(0.0), penumbra(5.0), penumbra(15.0)
    assert hard < soft < softer
    assert softer > 2 * max(hard, 1)


def test_large_scene_keeps_the_delta_sun_and_says_so(mi_scalar):
    size = 3 * SUN_DISK_MAX_DISTANCE / SUN_DISK_MIN_DISTANCE
    tr = MitsubaTranslator(resolve_settings(samples=4)).translate(_plane_under_sun(np.deg2rad(1.0), size=size))
    assert tr.scene_dict["light0000"]["type"] == "directional"
    assert any("light.sun.soft" in a and "delta" in a for a in tr.approximations)


def test_sun_disk_beyond_the_far_clip_needs_no_hiding(mi_scalar):
    """An opaque film with a sky: a sun's disk out of camera rays' reach is not a light shape to hide (no
    hide_emitters, no extra sky pass); with a far clip that reaches it, it is hidden like the other lights."""
    scene = _plane_under_sun(np.deg2rad(2.0))
    scene.lights.set_background_light(0.5, (0.3, 0.4, 0.6))
    settings = resolve_settings(samples=4, transparent_background=False)
    tr = MitsubaTranslator(settings).translate(scene)
    assert tr.scene_dict["light0000"]["type"] == "disk"
    assert tr.integrator["hide_emitters"] is False and tr.background_dict is None
    scene.camera.far = 1e6
    tr = MitsubaTranslator(settings).translate(scene)
    assert tr.integrator["hide_emitters"] is True and tr.background_dict is not None
