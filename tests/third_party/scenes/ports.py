"""Realistic scenes nobody here designed: ports of public example scenes into the IR.

Each builder re-creates one public example's objects, materials, lights and camera from the numbers its
source states (no code or asset of the source is copied; assets the repository does not have are left
out or replaced, as each docstring says). ``PORTS`` lists them with their source and licence; the same
rows are in tests/third_party/SOURCES.md, the licence texts in tests/third_party/scenes/LICENSES.md.

Conventions: y-up sources are turned into the IR's z-up frame by (x, y, z) -> (x, -z, y). Light
intensities of engines with other units are chosen for a similar exposure (stated per scene); a
cross-check compares engines on the *same* IR scene, so the port need not match the source's pixels.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np

import blendify_core as bf
from blendify_core.testing import data_path, look_at_camera


class Port(NamedTuple):
    build: Callable[..., bf.Scene]
    source: str
    licence: str
    open_licence: bool  # CC0 / CC-BY / MIT / BSD / Apache: may be redistributed
    note: str


def _yup(p: object) -> tuple[float, float, float]:
    x, y, z = (float(v) for v in np.asarray(p, dtype=float))
    return (x, -z, y)


def _fov_x(fov_y_deg: float, resolution: tuple[int, int]) -> float:
    """Horizontal field of view (radians) of a camera with vertical field of view ``fov_y_deg``."""
    w, h = resolution
    return float(2 * np.arctan(np.tan(np.deg2rad(fov_y_deg) / 2) * w / h))


_CUBE_V = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
_CUBE_F = np.array([[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]])


def _box(matrix: np.ndarray, yup: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """The cube [-1, 1]^3 transformed by a 3x4 / 4x4 matrix: (vertices, outward quads)."""
    m = np.asarray(matrix, dtype=float)
    v = _CUBE_V @ m[:3, :3].T + m[:3, 3]
    if yup:
        v = np.stack([v[:, 0], -v[:, 2], v[:, 1]], axis=1)
    return v, _CUBE_F.copy()


def _quad(corners: list[tuple[float, float, float]], facing: tuple[float, float, float]) -> np.ndarray:
    """Four corners ordered so that the quad's normal points along ``facing``."""
    c = np.asarray(corners, dtype=float)
    n = np.cross(c[1] - c[0], c[2] - c[0])
    return c if float(n @ np.asarray(facing, float)) > 0 else c[::-1].copy()


# ---------------------------------------------------------------------------------------------------
# open licences
# ---------------------------------------------------------------------------------------------------
def mitsuba_cbox(resolution: tuple[int, int] = (64, 64)) -> bf.Scene:
    """Mitsuba 3's built-in Cornell box (``mitsuba.cornell_box()``): five diffuse walls (white, red, green
    spectral-fit RGB reflectances), two rotated white boxes, a warm rectangular area light under the
    ceiling (radiance (18.387, 13.9873, 6.75357) over 0.46 x 0.38 -> power pi L A), camera 3.9 from the
    centre with a 39.3077 deg field of view. Lambertian, indirect light: the global-illumination case."""
    s = bf.Scene()
    white = (0.885809, 0.698859, 0.666422)
    red = (0.570068, 0.0430135, 0.0443706)
    green = (0.105421, 0.37798, 0.076425)
    walls = {  # Mitsuba (y-up) corners, the direction they face (into the box)
        "floor": ([(-1, -1, -1), (1, -1, -1), (1, -1, 1), (-1, -1, 1)], (0, 1, 0), white),
        "ceiling": ([(-1, 1, -1), (1, 1, -1), (1, 1, 1), (-1, 1, 1)], (0, -1, 0), white),
        "back": ([(-1, -1, -1), (1, -1, -1), (1, 1, -1), (-1, 1, -1)], (0, 0, 1), white),
        "red_wall": ([(-1, -1, -1), (-1, 1, -1), (-1, 1, 1), (-1, -1, 1)], (1, 0, 0), red),
        "green_wall": ([(1, -1, -1), (1, 1, -1), (1, 1, 1), (1, -1, 1)], (-1, 0, 0), green),
    }
    for tag, (corners, facing, colour) in walls.items():
        c = _quad(corners, facing)
        v = np.array([_yup(p) for p in c])
        s.renderables.add_mesh(
            v, np.array([[0, 1, 2, 3]]), bf.DiffuseMaterial(), bf.UniformColors(colour, color_space="linear"), tag=tag
        )
    large = [[0.28491, 0, 0.0939491, -0.33], [0, 0.61, 0, -0.4], [-0.0939491, 0, 0.28491, -0.28]]
    small = [[0.286891, 0, -0.0877115, 0.335], [0, 0.3, 0, -0.7], [0.0877115, 0, 0.286891, 0.38]]
    for tag, m in (("large_box", large), ("small_box", small)):
        v, f = _box(np.array(m), yup=True)
        s.renderables.add_mesh(v, f, bf.DiffuseMaterial(), bf.UniformColors(white, color_space="linear"), tag=tag)
    radiance = np.array([18.387, 13.9873, 6.75357])
    area = 0.46 * 0.38
    s.lights.add_area(
        "rectangle",
        (0.46, 0.38),
        strength=float(np.pi * radiance.max() * area),
        color=tuple(radiance / radiance.max()),
        color_space="linear",
        translation=_yup((0, 0.99, 0.01)),
        tag="light",
    )
    look_at_camera(s, resolution, _yup((0, 0, 3.9)), (0, 0, 0), fov_x=np.deg2rad(39.3077), near=0.01, far=100)
    return s


def pyrender_example(resolution: tuple[int, int] = (96, 72)) -> bf.Scene:
    """pyrender's ``examples/example.py``: the fuze bottle (tests/data), a 10 cm box with random per-vertex
    colours and one with random per-face colours (seeded here; the example draws them unseeded), a
    directional light and a spot light (inner pi/16, outer pi/6) at the camera pose, ambient 0.02, camera
    with a 60 deg vertical field of view. Left out: the drill, wood block and water bottle (their files are
    not in this repository). The materials are Lambertian (pyrender's default metallic-roughness material
    is not modelled); the directional light's 1.0 and the spot's 10 become a 2 W/m^2 sun and a 60 W spot."""
    import trimesh

    rng = np.random.default_rng(0)
    s = bf.Scene()
    tm = trimesh.load(data_path("fuze.obj"), process=False)
    tex = np.asarray(tm.visual.material.image.convert("RGB").resize((256, 256)))
    s.renderables.add_mesh(
        np.asarray(tm.vertices, float),
        np.asarray(tm.faces),
        bf.DiffuseMaterial(),
        bf.TextureColors(tex, bf.VertexUV(np.asarray(tm.visual.uv, float))),
        translation=(0.1, 0.15, -float(np.min(tm.vertices[:, 2]))),
        smooth=True,
        tag="fuze",
    )
    v, f = _box(np.diag([0.05, 0.05, 0.05, 1.0]))
    s.renderables.add_mesh(
        v,
        f,
        bf.DiffuseMaterial(),
        bf.VertexColors(rng.uniform(size=(8, 3))),
        translation=(-0.1, 0.10, 0.05),
        tag="box_vertex_colours",
    )
    # per-face colours: every triangle gets its own three vertices of one colour
    tri = np.concatenate([[q[[0, 1, 2]], q[[0, 2, 3]]] for q in f])
    face_colours = np.repeat(rng.uniform(size=(len(tri), 3)), 3, axis=0)
    s.renderables.add_mesh(
        v[tri.reshape(-1)],
        np.arange(3 * len(tri)).reshape(-1, 3),
        bf.DiffuseMaterial(),
        bf.VertexColors(face_colours),
        translation=(-0.1, -0.10, 0.05),
        tag="box_face_colours",
    )
    r2 = np.sqrt(2) / 2
    pose = np.array([[0.0, -r2, r2, 0.5], [1.0, 0.0, 0.0, 0.0], [0.0, r2, r2, 0.4]])
    position, forward = pose[:, 3], -pose[:, 2]
    look_at_camera(s, resolution, position, position + forward, fov_x=_fov_x(60.0, resolution), near=0.01, far=10)
    s.lights.add_sun(2.0, rotation_mode="look_at", rotation=tuple(position + forward), translation=tuple(position))
    s.lights.add_spot(
        60.0,
        spot_size=np.pi / 3,
        spot_blend=1 - (np.pi / 16) / (np.pi / 6),
        shadow_soft_size=0.0,
        rotation_mode="look_at",
        rotation=tuple(position + forward),
        translation=tuple(position),
    )
    s.lights.set_background_light(0.02)
    return s


def open3d_render_to_image(resolution: tuple[int, int] = (96, 72)) -> bf.Scene:
    """Open3D's ``examples/python/visualization/render_to_image.py``: a green cylinder (r 0.05, 3 tall), a
    yellow sphere (r 0.2) on top of it, a grey 2 x 2 x 1 box and a white icosahedron (r 0.5, flat) on the
    box, a sun along (0.707, 0, -0.707), camera at (0, 10, 0) looking at the origin with a 60 deg vertical
    field of view. Open3D's "defaultLit" material (roughness 1, no metal) is taken as Lambertian; the sun's
    75000 lux becomes 3 W/m^2, Open3D's default image-based light a uniform 0.3 sky; the axes helper is
    left out."""
    s = bf.Scene()
    mat = bf.DiffuseMaterial
    s.renderables.add_cylinder_mesh(
        0.05, 3.0, mat(), bf.UniformColors((0.0, 0.5, 0.0)), translation=(-2, 0, 1.5), tag="cyl"
    )
    s.renderables.add_sphere_nurbs(0.2, mat(), bf.UniformColors((1.0, 0.75, 0.0)), translation=(-2, 0, 3), tag="sphere")
    v, f = _box(np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 0.5, 0.5]]))
    s.renderables.add_mesh(v, f, mat(), bf.UniformColors((0.7, 0.7, 0.7)), tag="box")
    g = (1 + 5**0.5) / 2
    ico = np.array(
        [
            [-1, g, 0],
            [1, g, 0],
            [-1, -g, 0],
            [1, -g, 0],
            [0, -1, g],
            [0, 1, g],
            [0, -1, -g],
            [0, 1, -g],
            [g, 0, -1],
            [g, 0, 1],
            [-g, 0, -1],
            [-g, 0, 1],
        ],
        dtype=float,
    )
    ico *= 0.5 / np.linalg.norm(ico[0])
    faces = np.array(
        [
            [0, 11, 5],
            [0, 5, 1],
            [0, 1, 7],
            [0, 7, 10],
            [0, 10, 11],
            [1, 5, 9],
            [5, 11, 4],
            [11, 10, 2],
            [10, 7, 6],
            [7, 1, 8],
            [3, 9, 4],
            [3, 4, 2],
            [3, 2, 6],
            [3, 6, 8],
            [3, 8, 9],
            [4, 9, 5],
            [2, 4, 11],
            [6, 2, 10],
            [8, 6, 7],
            [9, 8, 1],
        ]
    )
    s.renderables.add_mesh(ico, faces, mat(), bf.UniformColors((1.0, 1.0, 1.0)), translation=(0, 0, 1.75), tag="solid")
    s.lights.add_sun(3.0, rotation_mode="eulerXYZ", rotation=(0, -45, 0))
    s.lights.set_background_light(0.3)  # Open3D's renderer adds a default image-based light
    look_at_camera(s, resolution, (0, 10, 0), (0, 0, 0), fov_x=_fov_x(60.0, resolution))
    return s


def threejs_lights_physical(resolution: tuple[int, int] = (96, 72)) -> bf.Scene:
    """three.js ``examples/webgl_lights_physical.html``: a 20 x 20 floor (roughness 0.8, metalness 0.2), a
    metal ball (r 0.25, roughness 0.5), three 0.5 m boxes (roughness 0.7, metalness 0.2), a 2 cm
    incandescent bulb (colour #ffee88) 2 m above the floor, camera at (-4, 2, 4) (y-up) looking at the
    origin with a 50 deg vertical field of view. The textures (hardwood, brick, earth) are not in this
    repository: plain white instead. The bulb's 400 lm (shown with exposure 0.68^5) becomes a 200 W
    point light; the 0.0001 lx hemisphere light is left out."""
    s = bf.Scene()
    s.renderables.add_plane_mesh(
        20.0, bf.PrincipledBSDFMaterial(roughness=0.8, metallic=0.2), bf.UniformColors((1, 1, 1)), tag="floor"
    )
    s.renderables.add_sphere_nurbs(
        0.25,
        bf.PrincipledBSDFMaterial(roughness=0.5, metallic=1.0),
        bf.UniformColors((1, 1, 1)),
        translation=_yup((1, 0.25, 1)),
        tag="ball",
    )
    for i, p in enumerate([(-0.5, 0.25, -1), (0, 0.25, -5), (7, 0.25, 0)]):
        s.renderables.add_cube_mesh(
            0.5,
            bf.PrincipledBSDFMaterial(roughness=0.7, metallic=0.2),
            bf.UniformColors((1, 1, 1)),
            translation=_yup(p),
            tag=f"box{i}",
        )
    s.lights.add_point(200.0, color=(1.0, 0xEE / 255, 0x88 / 255), shadow_soft_size=0.02, translation=_yup((0, 2, 0)))
    look_at_camera(s, resolution, _yup((-4, 2, 4)), (0, 0, 0), fov_x=_fov_x(50.0, resolution))
    return s


def kubric_helloworld(resolution: tuple[int, int] = (64, 64)) -> bf.Scene:
    """Kubric's ``examples/helloworld.py``: a 20 x 20 x 0.2 floor slab (a unit cube scaled (10, 10, 0.1) at
    z = -0.1), a unit-radius ball at z = 0.5 (half sunk into the floor, as in the example), a directional
    light from (-1, -0.5, 3) towards the origin with intensity 1.5, camera at (2, -0.5, 4) looking at the
    origin (Kubric's default 35 mm lens on a 32 mm sensor). Kubric's default Principled material, with
    Blender's default 0.8 grey."""
    s = bf.Scene()
    grey = bf.UniformColors((0.8, 0.8, 0.8), color_space="linear")
    v, f = _box(np.array([[10, 0, 0, 0], [0, 10, 0, 0], [0, 0, 0.1, -0.1]]))
    s.renderables.add_mesh(v, f, bf.PrincipledBSDFMaterial(), grey, tag="floor")
    s.renderables.add_sphere_nurbs(1.0, bf.PrincipledBSDFMaterial(), grey, translation=(0, 0, 0.5), tag="ball")
    s.lights.add_sun(1.5, rotation_mode="look_at", rotation=(0, 0, 0), translation=(-1, -0.5, 3))
    look_at_camera(s, resolution, (2, -0.5, 4), (0, 0, 0), fov_x=2 * np.arctan(16 / 35))
    return s


# ---------------------------------------------------------------------------------------------------
# GPL sources (their numbers re-created here; counted as not openly licensed)
# ---------------------------------------------------------------------------------------------------
def blendify_nurbs_primitives(resolution: tuple[int, int] = (96, 54)) -> bf.Scene:
    """blendify 2.1's ``examples/06_nurbs_primitives_render.py``: a sphere (r 1), a circle (r 0.7), a
    cylinder (r 1.3, 2.3 high) and a NURBS curve (thickness 0.1) through (1, 0, 0), (-1, 0, 0),
    (0, -2, -4), (-1, -3, -6), all with the default Principled material, a sun of strength 5 and the
    camera at the origin looking down -Z (focal length 640 px at 1280 x 720, scaled to ``resolution``)."""
    s = bf.Scene()
    mat = bf.PrincipledBSDFMaterial
    s.renderables.add_sphere_nurbs(1.0, mat(), bf.UniformColors((0.3, 0, 0.9)), translation=(0, 0, -4.5), tag="sphere")
    s.renderables.add_circle_mesh(0.7, mat(), bf.UniformColors((0.5, 0.3, 0.9)), translation=(0, 1, -4.5), tag="circle")
    s.renderables.add_cylinder_mesh(
        1.3, 2.3, mat(), bf.UniformColors((0.0, 0.9, 0.9)), translation=(1, 1, -8), tag="cylinder"
    )
    keys = np.array([[1, 0, 0.0], [-1, 0, 0], [0, -2, -4], [-1, -3, -6]])
    s.renderables.add_curve_nurbs(keys, 0.1, mat(), bf.UniformColors((1.0, 0.0, 0.2)), tag="curve")
    s.set_perspective_camera(resolution, focal_dist=640 * resolution[0] / 1280)
    s.lights.add_sun(5.0)
    return s


def blendify_readme_cube(resolution: tuple[int, int] = (64, 64)) -> bf.Scene:
    """blendify 2.1's README example: a 1 m green cube with the default Principled material, a 1000 W point
    light at (4, -2, 4), camera at (5, -5, 5) with quaternion (0.82, 0.42, 0.18, 0.34) and fov_x 0.7."""
    s = bf.Scene()
    s.lights.add_point(strength=1000.0, translation=(4, -2, 4))
    s.set_perspective_camera(resolution, fov_x=0.7, rotation=(0.82, 0.42, 0.18, 0.34), translation=(5, -5, 5))
    s.renderables.add_cube_mesh(1.0, bf.PrincipledBSDFMaterial(), bf.UniformColors((0.0, 1.0, 0.0)), tag="cube")
    return s


def blender_default_scene(resolution: tuple[int, int] = (96, 54)) -> bf.Scene:
    """Blender's startup scene (2.8+): the 2 m default cube with the default Principled material (0.8 grey,
    roughness 0.5), the 1000 W point light (radius 0.1) at (4.0762, 1.0055, 5.9039), the camera at
    (7.3589, -6.9258, 4.9583) with Euler XYZ (63.559, 0, 46.692) deg and a 50 mm lens on a 36 mm sensor,
    and the world's 0.050876 grey background."""
    s = bf.Scene()
    s.renderables.add_cube_mesh(
        2.0,
        bf.PrincipledBSDFMaterial(roughness=0.5),
        bf.UniformColors((0.8, 0.8, 0.8), color_space="linear"),
        tag="Cube",
    )
    s.lights.add_point(strength=1000.0, shadow_soft_size=0.1, translation=(4.0762, 1.0055, 5.9039), tag="Light")
    s.set_perspective_camera(
        resolution,
        fov_x=2 * np.arctan(18 / 50),
        rotation_mode="eulerxyz",  # Blender's "XYZ Euler" is extrinsic (world axes)
        rotation=(63.559, 0.0, 46.692),
        translation=(7.3589, -6.9258, 4.9583),
    )
    s.lights.set_background_light(1.0, (0.050876,) * 3)
    return s


PORTS: dict[str, Port] = {
    "mitsuba_cbox": Port(
        mitsuba_cbox,
        "Mitsuba 3 `mitsuba.cornell_box()` (github.com/mitsuba-renderer/mitsuba3, src/python/python/util.py)",
        "BSD-3-Clause",
        True,
        "Lambertian, area light, indirect light",
    ),
    "pyrender_example": Port(
        pyrender_example,
        "pyrender `examples/example.py` (github.com/mmatl/pyrender); fuze.obj from tests/data",
        "MIT",
        True,
        "textured + vertex-coloured meshes, sun + spot + ambient",
    ),
    "open3d_render_to_image": Port(
        open3d_render_to_image,
        "Open3D `examples/python/visualization/render_to_image.py` (github.com/isl-org/Open3D)",
        "MIT",
        True,
        "primitives + a flat icosahedron under a sun",
    ),
    "threejs_lights_physical": Port(
        threejs_lights_physical,
        "three.js `examples/webgl_lights_physical.html` (github.com/mrdoob/three.js)",
        "MIT",
        True,
        "Principled metal/dielectric, a small bulb",
    ),
    "kubric_helloworld": Port(
        kubric_helloworld,
        "Kubric `examples/helloworld.py` (github.com/google-research/kubric)",
        "Apache-2.0",
        True,
        "Principled floor and ball, sun",
    ),
    "blendify_nurbs_primitives": Port(
        blendify_nurbs_primitives,
        "blendify 2.1 `examples/06_nurbs_primitives_render.py` (github.com/ptrvilya/blendify)",
        "GPL-3.0",
        False,
        "NURBS sphere/curve, circle, cylinder, Principled, sun",
    ),
    "blendify_readme_cube": Port(
        blendify_readme_cube,
        "blendify 2.1 README example (github.com/ptrvilya/blendify)",
        "GPL-3.0",
        False,
        "Principled cube, strong point light, quaternion camera",
    ),
    "blender_default_scene": Port(
        blender_default_scene,
        "Blender's startup file (default cube, light, camera, world; blender.org)",
        "GPL-2.0-or-later",
        False,
        "Principled cube, point light with radius, grey world",
    ),
}
