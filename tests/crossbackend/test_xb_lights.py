"""Lights across backends: a light that casts no shadow (``use_shadow=False``) over a plane with an
occluding cube renders the same in Cycles and Mitsuba (Mitsuba's integrator 'blendify_path'), at every
light type; the light's would-be shadow is lit in both."""

from __future__ import annotations

import numpy as np
import pytest
from xb_util import require

import blendify_core as bf
from blendify_core import testing

#: point and area run by default; the other types are slow (each ~7 s on 2 cores)
LIGHTS = (
    "point",
    "area",
    pytest.param("sun", marks=pytest.mark.slow),
    pytest.param("spot", marks=pytest.mark.slow),
    pytest.param("area_disk", marks=pytest.mark.slow),
)


def _render(backend: str, light: str, use_shadow: bool) -> bf.RenderResult:
    samples = 64
    scene = testing.occluder_scene(light, use_shadow, resolution=(24, 24))
    return bf.render(
        scene, backend=backend, samples=samples, seed=0, outputs=("rgb", "instance"), pixel_filter="box", denoise=False
    )


@pytest.mark.parametrize("light", LIGHTS)
def test_no_shadow_lights_cycles_vs_mitsuba(light):
    require("cycles")
    require("mitsuba")
    c = _render("cycles", light, False)
    m = _render("mitsuba", light, False)
    shadowed = _render("cycles", light, True)
    plane = (c.instance == 0) & (m.instance == 0)
    shadow = plane & (shadowed.rgba[..., 0] < 0.8 * c.rgba[..., 0])
    assert shadow.sum() >= 4, "the cube must cast a shadow when the light casts shadows"
    for name, region in (("plane", plane), ("would-be shadow", shadow)):
        a, b = c.rgba[region, :3].mean(), m.rgba[region, :3].mean()
        print(f"{light} {name}: cycles {a:.4f} mitsuba {b:.4f} ratio {b / a:.4f}")
        assert abs(b / a - 1) < 0.02
    per_pixel = np.abs(m.rgba[plane, 0] / c.rgba[plane, 0] - 1)
    assert np.median(per_pixel) < (0.05 if light.startswith("area") else 0.01)
