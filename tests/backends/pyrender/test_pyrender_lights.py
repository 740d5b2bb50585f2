"""Every pair of light types with every combination of shadow flags renders in pyrender (two lights, one
casting shadows and one not, used to fail in pyrender's shadow pass), and each light keeps its own flag:
the picture of a pair is the sum of the pictures of its lights alone."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from blendify_core import render, testing

pytestmark = pytest.mark.pyrender

KINDS = ("point", "sun", "spot", "area_square", "area_disk")


def _add(scene, kind: str, shadow: bool, x: float) -> None:
    lights = scene.lights
    if kind == "point":
        lights.add_point(strength=20.0, translation=(x, 0, 2.0), use_shadow=shadow)
    elif kind == "sun":
        lights.add_sun(strength=1.0, use_shadow=shadow, rotation_mode="eulerXYZ", rotation=(0, 10 * x, 0))
    elif kind == "spot":
        lights.add_spot(strength=40.0, translation=(x, 0, 2.0), use_shadow=shadow)
    else:
        shape = "square" if kind == "area_square" else "circle"
        lights.add_area(shape, 0.5, strength=20.0, translation=(x, 0, 1.5), use_shadow=shadow)


def _scene(lights: list[tuple[str, bool, float]]):
    scene = testing.occluder_scene("point", True, (24, 24))
    for light in list(scene.lights):
        scene.lights.remove(light.tag)
    for kind, shadow, x in lights:
        _add(scene, kind, shadow, x)
    return scene


@pytest.mark.parametrize("a,b", list(itertools.combinations_with_replacement(KINDS, 2)))
def test_every_pair_of_lights_and_shadow_flags(pyr, a, b):
    for sa, sb in itertools.product((True, False), repeat=2):
        one = (a, sa, -0.3)
        two = (b, sb, 0.3)
        both = render(_scene([one, two]), backend=pyr, quality="preview", outputs=("rgb", "instance"))
        alone = [render(_scene([x]), backend=pyr, quality="preview").rgba[..., :3] for x in (one, two)]
        plane = both.instance == 0
        assert np.isfinite(both.rgba).all()
        # each light keeps its own shadow flag: the pair is the sum of the lights alone (8-bit output)
        total = (alone[0] + alone[1])[plane]
        err = np.abs(both.rgba[..., :3][plane] - total).mean() / total.mean()
        assert err < 0.03, f"{a} (shadow={sa}) + {b} (shadow={sb}): {err:.3f}"


@pytest.mark.parametrize("kind", ["sun", "spot", "area_square", "area_disk"])
def test_no_shadow_acne_on_a_lit_plane(pyr, kind):
    """A plane with nothing above it looks the same whether a tilted light 1 m above casts shadows or not: no
    self-shadowing (pyrender's own depth bias left sparse pixels up to 3 % darker under area lights)."""
    pose = dict(translation=(0, 0, 1.0), rotation_mode="eulerXYZ", rotation=(15, 0, 30))
    images = []
    for shadow in (True, False):
        scene = testing.plane_scene("point", resolution=(48, 48))
        for light in list(scene.lights):
            scene.lights.remove(light.tag)
        if kind == "sun":
            scene.lights.add_sun(strength=1.0, use_shadow=shadow, rotation_mode="eulerXYZ", rotation=(15, 0, 30))
        elif kind == "spot":
            scene.lights.add_spot(strength=15.0, spot_size=np.deg2rad(120), use_shadow=shadow, **pose)
        else:
            shape = "square" if kind == "area_square" else "circle"
            scene.lights.add_area(shape, 0.5, strength=15.0, use_shadow=shadow, **pose)
        images.append(render(scene, backend=pyr, quality="preview").rgba[..., :3])
    diff = np.abs(images[0] - images[1])
    print(f"{kind}: max difference with/without shadows {diff.max():.4f}")
    assert diff.max() < 1.5 / 255
