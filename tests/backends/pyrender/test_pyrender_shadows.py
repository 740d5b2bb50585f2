"""Soft shadows in the preview: lights with a size (suns with an angular diameter, area lights, spot lights with
a radius) cast penumbrae of about the width similar triangles give; lights without one stay hard."""

from __future__ import annotations

import numpy as np
import pytest

from blendify_core import DiffuseMaterial, Scene, UniformColors, render

pytestmark = pytest.mark.pyrender

#: orthographic view from +Z of x in [-0.5, 1.5]: 32 pixels per metre
PX_PER_M = 32.0
EDGE_HEIGHT = 0.5


def _scene(light: str, size: float, occluder: bool) -> Scene:
    """A grey floor seen from above; an occluding sheet over x < 0 at height 0.5 (optional); one light casting
    the sheet's edge shadow toward +x."""
    scene = Scene()
    scene.set_orthographic_camera((64, 8), ortho_scale=2.0, translation=(0.5, 0, 5.0), near=0.1, far=20)
    grey = UniformColors((0.5, 0.5, 0.5), color_space="linear")
    scene.renderables.add_plane_mesh(6.0, DiffuseMaterial(), grey, tag="floor")
    if occluder:
        scene.renderables.add_plane_mesh(2.0, DiffuseMaterial(), grey, translation=(-1.0, 0, EDGE_HEIGHT), tag="sheet")
    if light == "sun":  # 30 degrees from the vertical, toward +x
        scene.lights.add_sun(3.0, angular_diameter=size, rotation_mode="eulerXYZ", rotation=(0, -30, 0))
    elif light == "area":  # a square centred 1 m to the left of the edge, 2.5 m up, facing down
        scene.lights.add_area("square", size, strength=300.0, translation=(-1.0, 0, 2.5))
    else:
        scene.lights.add_spot(300.0, spot_size=np.deg2rad(150), shadow_soft_size=size, translation=(-1.0, 0, 2.5))
    return scene


def _visibility(pyr, light: str, size: float) -> np.ndarray:
    """Floor luminance with the sheet / without it, per column (mean over the rows)."""
    lit, free = (render(_scene(light, size, occ), backend=pyr, quality="preview").rgba for occ in (True, False))
    lit, free = (img[..., :3].mean(axis=(0, 2)) for img in (lit, free))
    return lit / np.maximum(free, 1e-6)


def _ramp_width(vis: np.ndarray) -> float:
    """Metres between the columns where the visibility (right of the edge, x > 0.05) first exceeds 0.1 and 0.9."""
    x = -0.5 + (np.arange(vis.size) + 0.5) / PX_PER_M
    v = np.where(x > 0.05, vis, 0.0)
    assert v[-1] > 0.95, "the floor at the right is unshadowed"
    return float(x[np.argmax(v > 0.9)] - x[np.argmax(v > 0.1)])


@pytest.mark.parametrize(
    "light,size,expected",
    [
        # sun 30 deg from the vertical, 20 deg wide: h (tan(40 deg) - tan(20 deg))
        ("sun", np.deg2rad(20.0), EDGE_HEIGHT * (np.tan(np.deg2rad(40)) - np.tan(np.deg2rad(20)))),
        # light 1 m wide 1 m left of the edge, 2 m above its height: 1 m x 0.5 / 2
        ("area", 1.0, 0.25),
        # a spot of radius 0.4 at the same place: 0.8 m x 0.5 / 2
        ("spot", 0.4, 0.2),
    ],
)
def test_penumbra_width_follows_the_light_size(pyr, light, size, expected):
    soft = _ramp_width(_visibility(pyr, light, size))
    hard = _ramp_width(_visibility(pyr, light, 1e-3 if light != "sun" else 0.0))
    print(f"{light}: 10-90 % ramp {soft:.3f} m (full penumbra {expected:.3f} m), hard {hard:.3f} m")
    assert hard <= 2.5 / PX_PER_M
    # the 10-90 % part of a penumbra of width w: 0.6-0.9 w for discs and squares; PCSS's estimate within 35 %
    assert 0.5 * expected <= soft <= 1.2 * expected


def test_environment_sun_has_the_size_of_its_pixels():
    from blendify_pyrender.translate import environment_light, environment_sun

    from blendify_core.ir.lights import EnvironmentMap

    h, w = 64, 128
    img = np.full((h, w, 3), 0.1, dtype=np.float32)
    v = 1.0 - (np.arange(h) + 0.5) / h
    lat = np.pi * (v - 0.5)[:, None]
    lon = 2 * np.pi * (0.5 - (np.arange(w) + 0.5) / w)[None, :]
    d = np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat) * np.ones_like(lon)], axis=-1)
    sun = np.array([0.0, np.cos(np.deg2rad(50)), np.sin(np.deg2rad(50))])
    img[d @ sun > np.cos(np.deg2rad(6.0))] = 200.0  # a disc 12 degrees wide
    light = environment_sun(environment_light(EnvironmentMap(img, color_space="linear")))
    assert light is not None
    assert np.rad2deg(light.angular_diameter) == pytest.approx(12.0, rel=0.15)
