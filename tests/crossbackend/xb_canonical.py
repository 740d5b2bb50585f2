"""The canonical cross-backend scenes (issue 6): shared by tests/crossbackend/test_xb_canonical.py and
benchmarks/crosscheck_report.py, so the measured agreement table describes exactly the tested scenes.

Each entry: name -> (builder, samples, note). Builders return small scenes (<= 128 px)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

import blendify_core as bf
from blendify_core.testing import (
    bunny_scene,
    data_path,
    look_at_camera,
    marker_scene,
    plane_scene,
    pointcloud_scene,
    primitives_scene,
    textured_quad_scene,
)


def fuze_scene(resolution: tuple[int, int] = (96, 128)) -> bf.Scene:
    """The textured bottle (tests/data/fuze.obj + its JPEG, per-vertex UVs), sun + sky."""
    import trimesh
    from PIL import Image

    tm = trimesh.load(data_path("fuze.obj"), process=False)
    tex = tm.visual.material.image.convert("RGB").resize((256, 256), Image.BILINEAR)
    scene = bf.Scene()
    scene.renderables.add_mesh(
        np.asarray(tm.vertices, dtype=np.float64),
        np.asarray(tm.faces),
        bf.DiffuseMaterial(),
        bf.TextureColors(np.asarray(tex), bf.VertexUV(np.asarray(tm.visual.uv, dtype=np.float64))),
        smooth=True,
        tag="fuze",
    )
    look_at_camera(scene, resolution, (0.25, -0.35, 0.2), (0, 0, 0.11), fov_x=np.deg2rad(30))
    scene.lights.add_sun(3.0, angular_diameter=0.0, rotation_mode="eulerXYZ", rotation=(40, 10, 30))
    scene.lights.set_background_light(0.3)
    return scene


def faces_material_scene(resolution: tuple[int, int] = (96, 72)) -> bf.Scene:
    """A cube and a pyramid with per-face materials (two diffuse colours), lit by a delta sun."""
    scene = bf.Scene()
    red, green = bf.UniformColors((0.8, 0.1, 0.1)), bf.UniformColors((0.1, 0.7, 0.2))
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 0.5, 1]], dtype=float) - [0.5, 0.5, 0]
    f = np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4], [0, 2, 1], [0, 3, 2]])
    scene.renderables.add_mesh(
        v,
        f,
        [bf.DiffuseMaterial(), bf.DiffuseMaterial()],
        [red, green],
        faces_material=[0, 1, 0, 1, 0, 0],
        translation=(-0.7, 0, 0),
        tag="pyramid",
    )
    scene.renderables.add_cube_mesh(
        0.8,
        [bf.DiffuseMaterial(), bf.DiffuseMaterial()],
        [green, red],
        faces_material=[0, 1, 0, 1, 0, 1],
        translation=(0.8, 0, 0.4),
        rotation_mode="eulerXYZ",
        rotation=(0, 0, 30),
        tag="cube",
    )
    look_at_camera(scene, resolution, (1.5, -3.5, 2.5), (0, 0, 0.3), fov_x=np.deg2rad(45))
    scene.lights.add_sun(3.0, angular_diameter=0.0, rotation_mode="eulerXYZ", rotation=(35, 15, 20))
    return scene


def shadow_catcher_scene(resolution: tuple[int, int] = (96, 72)) -> bf.Scene:
    """A sphere on a shadow-catcher plane, delta sun + sky: only the shadow is kept on the plane."""
    scene = bf.Scene()
    scene.renderables.add_plane_mesh(
        6.0, bf.DiffuseMaterial(), bf.UniformColors((0.8, 0.8, 0.8)), shadow_catcher=True, tag="catcher"
    )
    scene.renderables.add_sphere_nurbs(
        0.5, bf.DiffuseMaterial(), bf.UniformColors((0.2, 0.5, 0.9)), translation=(0, 0, 0.5), tag="ball"
    )
    look_at_camera(scene, resolution, (0.0, -4.0, 2.5), (0, 0, 0.4), fov_x=np.deg2rad(45))
    scene.lights.add_sun(3.0, angular_diameter=0.0, rotation_mode="eulerXYZ", rotation=(30, 20, 0))
    scene.lights.set_background_light(0.3)
    return scene


def bunny_ortho_scene(resolution: tuple[int, int] = (96, 96)) -> bf.Scene:
    """The vertex-coloured bunny seen by an orthographic camera."""
    scene = bunny_scene(resolution)
    scene.set_orthographic_camera(
        resolution,
        ortho_scale=0.22,
        rotation_mode="look_at",
        rotation=np.array([0.0, 0.0, 0.07]),
        translation=(0.5, -0.7, 0.4),
        near=0.1,
        far=5.0,
    )
    return scene


def _markers(**kw: object) -> Callable[[], bf.Scene]:
    return lambda: marker_scene(**kw)[0]  # type: ignore[arg-type]


#: name -> (builder, samples per pixel, what it checks)
CANONICAL: dict[str, tuple[Callable[[], bf.Scene], int, str]] = {
    "markers": (
        _markers(resolution=(64, 48), fx=60.0, center=(33.3, 22.1), radius=0.3),
        64,
        "camera self-test: markers at projected points incl. corners, off-centre principal point",
    ),
    "markers_fx_ne_fy": (
        _markers(resolution=(64, 48), fx=60.0, fy=66.0, center=(30.2, 25.4), radius=0.3),
        64,
        "camera self-test with fx != fy (non-square pixels)",
    ),
    "markers_ortho": (
        _markers(resolution=(64, 48), orthographic=True, ortho_scale=4.0, center=(33.3, 22.1), radius=0.19),
        64,
        "camera self-test, orthographic",
    ),
    **{
        f"plane_{light}": (
            (lambda light=light: plane_scene(light)),
            256 if light.startswith("area") or light == "background" else 16,
            f"Lambertian plane (albedo 0.5) under a {light} light",
        )
        for light in ("point", "sun", "spot", "area", "area_disk", "background")
    },
    "textured_quad": (textured_quad_scene, 64, "2x2 texture: UV orientation"),
    "bunny": (lambda: bunny_scene((96, 96)), 256, "bunny with vertex colours (Principled, roughness 0.6), sun + sky"),
    "bunny_ortho": (bunny_ortho_scene, 256, "the bunny through an orthographic camera"),
    "fuze": (fuze_scene, 256, "textured mesh (fuze.obj, JPEG texture, per-vertex UVs)"),
    "pointcloud": (lambda: pointcloud_scene(n=500, resolution=(96, 96)), 128, "500 points with per-point colours"),
    "primitives": (lambda: primitives_scene((128, 96)), 128, "every primitive (cube, cylinder, sphere, ...)"),
    "faces_material": (faces_material_scene, 64, "per-face materials, delta sun"),
    "shadow_catcher": (shadow_catcher_scene, 128, "sphere on a shadow-catcher plane"),
}
