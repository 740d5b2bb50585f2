"""Scene builders shared by the test suite and the benchmarks (so benchmarked scenes are tested ones).

Every builder returns a fresh :class:`~blendify_core.Scene`; small resolutions by default.
"""

from __future__ import annotations

import os
import struct
import zlib
from pathlib import Path
from typing import Any

import numpy as np

from blendify_core.errors import InvalidSceneError
from blendify_core.ir.colors import FacesUV, NormalMap, TextureColors, TextureMap, UniformColors, VertexColors, VertexUV
from blendify_core.ir.geometry import torus, uv_sphere, vertex_normals
from blendify_core.ir.materials import (
    DiffuseMaterial,
    GlossyBSDFMaterial,
    MetalMaterial,
    PlasticMaterial,
    PlasticWireframeMaterial,
    PrincipledBSDFMaterial,
)
from blendify_core.ir.scene import Scene
from blendify_core.typing import AnyArray

__all__ = [
    "write_radiance_hdr",
    "write_png16",
    "rgbe_encode",
    "DATA_DIR",
    "data_path",
    "third_party_path",
    "THIRD_PARTY_DIR",
    "THIRD_PARTY_ENV",
    "marker_scene",
    "plane_scene",
    "occluder_scene",
    "smooth_cylinder_scene",
    "depth_plane_scene",
    "bunny_scene",
    "textured_quad_scene",
    "pointcloud_scene",
    "primitives_scene",
    "every_feature_scene",
    "look_at_camera",
    "calibration_scene",
    "CALIBRATION_DEFECTS",
    "material_sphere_scene",
    "material_sphere_mask",
]

DATA_DIR = Path(__file__).resolve().parents[1] / "tests" / "data"
"""The repository's test data (``tests/data`` of the checkout: small files with their source and licence)."""


def data_path(name: str) -> Path:
    """Path of a file of the repository's test data (``tests/data``, see its README for sources and licences).

    The files ship with the source checkout, not with an installed wheel: outside a checkout this raises
    ``FileNotFoundError`` saying so.
    """
    path = DATA_DIR / name
    if not path.is_file():
        raise FileNotFoundError(
            f"test data {name!r} not found in {DATA_DIR}: the test data ships with the source checkout of "
            "blendify-core (tests/data), not with an installed package"
        )
    return path


#: the environment variable naming the local folder of third-party test scenes that are not committed
#: (their licence or size does not allow it); tests/third_party/SOURCES.md lists every third-party scene
#: (committed or not), where it comes from and its licence
THIRD_PARTY_ENV = "BLENDIFY_THIRD_PARTY_DIR"
THIRD_PARTY_DIR = Path(__file__).resolve().parents[1] / "tests" / "third_party"
"""Third-party scenes committed with the repository (open licences, small), one folder per source."""


def third_party_path(relative: str) -> Path:
    """A third-party test file: committed under ``tests/third_party/<relative>``, or else found in the local
    cache folder named by ``$BLENDIFY_THIRD_PARTY_DIR`` (same relative path). Raises FileNotFoundError saying
    which: tests catch it and skip with that reason (``pytest.skip(str(exc))``)."""
    committed = THIRD_PARTY_DIR / relative
    if committed.exists():
        return committed
    cache = os.environ.get(THIRD_PARTY_ENV)
    if cache and (Path(cache) / relative).exists():
        return Path(cache) / relative
    where = f"${THIRD_PARTY_ENV}={cache!r}" if cache else f"${THIRD_PARTY_ENV} is not set"
    raise FileNotFoundError(
        f"third-party test file {relative!r} is not committed and not in the local cache ({where}); "
        "tests/third_party/SOURCES.md says where to get it"
    )


def look_at_camera(
    scene: Scene, resolution: tuple[int, int], position: Any, target: Any = (0, 0, 0), **kwargs: Any
) -> Any:
    """Perspective camera at ``position`` looking at ``target`` (kwargs: fov_x/focal_dist/K/center/...)."""
    if not any(k in kwargs for k in ("fov_x", "fov_y", "focal_dist", "K")):
        kwargs["fov_x"] = np.deg2rad(40.0)
    return scene.set_perspective_camera(
        resolution, rotation_mode="look_at", rotation=np.asarray(target, float), translation=position, **kwargs
    )


def marker_points(scene: Scene, pixels: np.ndarray, depths: np.ndarray) -> np.ndarray:
    """World points that project to OpenCV pixel coordinates ``pixels`` at planar ``depths``."""
    cam = scene.camera
    r, t = cam.opencv_extrinsics()  # type: ignore[union-attr]
    x = (pixels[:, 0] - cam.cx) / cam.fx * depths  # type: ignore[union-attr]
    y = (pixels[:, 1] - cam.cy) / cam.fy * depths  # type: ignore[union-attr]
    p_cam = np.stack([x, y, depths], axis=1)
    return (p_cam - t) @ r


def marker_scene(
    resolution: tuple[int, int] = (160, 120),
    fx: float = 150.0,
    fy: float | None = None,
    center: tuple[float, float] | None = (83.3, 57.1),
    radius: float = 0.12,
    orthographic: bool = False,
    ortho_scale: float = 4.0,
    lit: bool = True,
) -> tuple[Scene, np.ndarray]:
    """The camera self-test: spheres placed by back-projecting chosen pixels (including near the
    corners) through a known K. Returns the scene and the (N, 2) expected OpenCV pixel centres of the
    markers (the projected sphere centres). Camera at (3, -4, 2.5) with a 12 degree roll."""
    scene = Scene()
    w, h = resolution
    fy = fx if fy is None else fy
    cx, cy = center if center is not None else ((w - 1) / 2, (h - 1) / 2)
    pose = dict(rotation_mode="look_at", rotation=(np.zeros(3), 12.0), translation=(3.0, -4.0, 2.5))
    if orthographic:
        scene.set_orthographic_camera(resolution, ortho_scale=ortho_scale, center=(cx, cy), **pose)  # type: ignore[arg-type]
    else:
        k = np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1.0]])
        scene.set_perspective_camera(resolution, K=k, **pose)  # type: ignore[arg-type]
    pixels = np.array(
        [
            [w * 0.5, h * 0.5],
            [12.0, 10.0],
            [w - 13.0, 11.0],
            [14.0, h - 12.0],
            [w - 12.5, h - 13.5],
            [w * 0.3, h * 0.62],
        ]
    )
    depths = np.array([5.0, 5.5, 6.0, 6.5, 5.8, 6.2])
    if not orthographic:
        pts = marker_points(scene, pixels, depths)
    else:
        cam = scene.camera
        r, t = cam.opencv_extrinsics()  # type: ignore[union-attr]
        s = cam.pixel_size  # type: ignore[union-attr]
        p_cam = np.stack([(pixels[:, 0] - cx) * s, (pixels[:, 1] - cy) * s, depths], axis=1)
        pts = (p_cam - t) @ r
        radius = radius * ortho_scale / 4.0
    mat = DiffuseMaterial()
    for i, p in enumerate(pts):
        scene.renderables.add_sphere_nurbs(
            radius, mat, UniformColors((0.8, 0.8, 0.8)), translation=p, tag=f"marker_{i}"
        )
    if lit:
        scene.lights.set_background_light(1.0, (1.0, 1.0, 1.0))
    return scene, pixels


def plane_scene(light: str = "sun", resolution: tuple[int, int] = (64, 64), albedo: float = 0.5) -> Scene:
    """The light-unit check: a Lambertian plane (reflectance ``albedo``, linear) facing +Z, an
    orthographic camera looking straight down, one light of type ``light`` (point, sun, spot, area,
    area_disk, background)."""
    scene = Scene()
    scene.set_orthographic_camera(resolution, ortho_scale=2.0, translation=(0, 0, 5.0), near=0.1, far=20)
    scene.renderables.add_plane_mesh(
        4.0, DiffuseMaterial(), UniformColors((albedo,) * 3, color_space="linear"), tag="plane"
    )
    if light == "point":
        scene.lights.add_point(strength=100.0, shadow_soft_size=0.0, translation=(0, 0, 2.0))
    elif light == "sun":
        scene.lights.add_sun(strength=3.0, angular_diameter=0.0, rotation_mode="eulerXYZ", rotation=(20, 0, 0))
    elif light == "spot":
        scene.lights.add_spot(
            strength=200.0, spot_size=np.deg2rad(120), spot_blend=0.0, shadow_soft_size=0.0, translation=(0, 0, 2.0)
        )
    elif light == "area":
        scene.lights.add_area("square", 0.5, strength=100.0, translation=(0, 0, 1.5))
    elif light == "area_disk":
        scene.lights.add_area("circle", 0.5, strength=100.0, translation=(0, 0, 1.5))
    elif light == "background":
        scene.lights.set_background_light(1.0, (1.0, 1.0, 1.0))
    else:
        raise ValueError(f"light: unknown light type {light!r}")
    return scene


def occluder_scene(
    light: str = "point", use_shadow: bool = True, resolution: tuple[int, int] = (32, 32), occluder: bool = True
) -> Scene:
    """:func:`plane_scene` with a Lambertian cube (side 0.4, tagged "cube") between the light and the plane,
    the light's ``use_shadow`` set: where the cube's shadow falls tells whether the light casts shadows."""
    scene = plane_scene(light, resolution=resolution)
    if occluder:
        scene.renderables.add_cube_mesh(
            0.4, DiffuseMaterial(), UniformColors((0.5,) * 3, color_space="linear"), translation=(0, 0, 0.8), tag="cube"
        )
    for lamp in scene.lights:
        lamp.use_shadow = use_shadow
    return scene


def smooth_cylinder_scene(resolution: tuple[int, int] = (64, 48), segments: int = 24) -> Scene:
    """A smooth-shaded cylinder (radius 0.5, height 1) built with ``add_mesh``: ``segments`` side quads and two
    ``segments``-gon caps sharing the rim vertices (so the rim's vertex normals mix cap and side: the case
    where angle and area weighting differ most), seen from above at an angle, under a sun."""
    scene = Scene()
    phi = np.arange(segments) * 2 * np.pi / segments
    ring = np.stack([0.5 * np.cos(phi), 0.5 * np.sin(phi)], axis=1)
    v = np.concatenate([np.c_[ring, np.full(segments, -0.5)], np.c_[ring, np.full(segments, 0.5)]])
    k = np.arange(segments)
    sides = [[i, (i + 1) % segments, segments + (i + 1) % segments, segments + i] for i in k]
    caps = [list(k[::-1]), list(segments + k)]
    mesh = scene.renderables.add_mesh(
        v, sides + caps, DiffuseMaterial(), UniformColors((0.6, 0.6, 0.6)), tag="cylinder"
    )
    mesh.set_smooth(True)
    look_at_camera(scene, resolution, (1.6, -1.9, 1.5), (0, 0, 0), fov_x=np.deg2rad(40))
    scene.lights.add_sun(3.0, angular_diameter=0.0, rotation_mode="eulerXYZ", rotation=(30, 10, 20))
    return scene


#: the material sphere's base colour (linear), centre and radius (:func:`material_sphere_scene`)
MATERIAL_SPHERE_BASE = (0.8, 0.35, 0.15)
MATERIAL_SPHERE_CENTRE = (0.0, 0.0, 1.0)


def material_sphere_scene(material: Any, resolution: tuple[int, int] = (64, 48)) -> Scene:
    """The material sweep's scene: a unit sphere at (0, 0, 1) with ``material`` and the linear base colour
    :data:`MATERIAL_SPHERE_BASE` on a Lambertian grey plane (0.5), one square area light (1.5 m, 400 W) to the
    upper right and a uniform background (0.3); the camera looks at the sphere from the front, above."""
    scene = Scene()
    look_at_camera(scene, resolution, (0.0, -4.6, 2.4), (0.0, 0.0, 0.85), fov_x=np.deg2rad(42))
    scene.renderables.add_sphere_nurbs(
        1.0,
        material,
        UniformColors(MATERIAL_SPHERE_BASE, color_space="linear"),
        translation=MATERIAL_SPHERE_CENTRE,
        tag="sphere",
    )
    scene.renderables.add_plane_mesh(
        12.0, DiffuseMaterial(), UniformColors((0.5, 0.5, 0.5), color_space="linear"), tag="plane"
    )
    scene.lights.add_area(
        "square",
        1.5,
        strength=400.0,
        rotation_mode="look_at",
        rotation=MATERIAL_SPHERE_CENTRE,
        translation=(2.5, -2.0, 4.0),
    )
    scene.lights.set_background_light(0.3)
    return scene


def material_sphere_mask(scene: Scene) -> np.ndarray:
    """(H, W) bool: the pixels of :func:`material_sphere_scene`'s sphere (the ray through the pixel centre
    passes within 0.985 radii of the centre): the whole visible sphere, grazing views included."""
    cam: Any = scene.camera
    o, d = cam.pixel_rays()
    oc = np.asarray(MATERIAL_SPHERE_CENTRE) - o
    t = np.einsum("ij,ij->i", oc, d)
    dist = np.linalg.norm(oc - t[:, None] * d, axis=1)
    return np.asarray((dist < 0.985).reshape(cam.height, cam.width))


def depth_plane_scene(resolution: tuple[int, int] = (64, 48), distance: float = 3.0, tilt_deg: float = 30.0) -> Scene:
    """A large plane through (0, 0, 0) tilted by ``tilt_deg`` about X, seen by a camera at (0, 0, distance)
    looking down -Z: planar depth is known analytically (see :func:`expected_plane_depth`)."""
    scene = Scene()
    scene.set_perspective_camera(resolution, fov_x=np.deg2rad(50), translation=(0, 0, distance), near=0.05, far=100)
    scene.renderables.add_plane_mesh(
        20.0,
        DiffuseMaterial(),
        UniformColors((0.5, 0.5, 0.5)),
        rotation_mode="eulerXYZ",
        rotation=(tilt_deg, 0, 0),
        tag="plane",
    )
    scene.lights.set_background_light(1.0)
    return scene


def expected_plane_depth(scene: Scene) -> np.ndarray:
    """Analytic planar depth (H, W) of the plane tagged "plane" (infinite plane; +inf where parallel/behind)."""
    cam = scene.camera
    plane = scene.renderables["plane"]
    n = plane.rotation_matrix[:, 2]
    p0 = plane.translation
    origins, dirs = cam.pixel_rays()  # type: ignore[union-attr]
    denom = dirs @ n
    with np.errstate(divide="ignore", invalid="ignore"):
        t = ((p0 - origins) @ n) / denom
    t = np.where(t > 0, t, np.inf)
    z = t * (dirs @ cam.viewdir)  # type: ignore[union-attr]
    return z.reshape(cam.height, cam.width).astype(np.float64)  # type: ignore[union-attr]


def bunny_scene(
    resolution: tuple[int, int] = (128, 128), vertex_colors: bool = True, plane: bool = True, light: str = "sun"
) -> Scene:
    """The Stanford bunny (``tests/data/bunny.ply``, +Y up rotated to +Z up) on a plane, lit by a sun
    (or an area light), with colours from its normals."""
    import trimesh

    tm: Any = trimesh.load(data_path("bunny.ply"), process=False)  # a Trimesh (trimesh types it as any geometry)
    v = np.asarray(tm.vertices, dtype=np.float64)
    v = v[:, [0, 2, 1]] * np.array([1, -1, 1])  # +Y up -> +Z up (right-handed)
    v -= [v[:, 0].mean(), v[:, 1].mean(), v[:, 2].min()]
    faces = np.asarray(tm.faces)[:, [0, 2, 1]]
    scene = Scene()
    if vertex_colors:
        n = vertex_normals(v, faces)
        colors: Any = VertexColors(np.clip(np.abs(n) * 0.8 + 0.1, 0, 1))
    else:
        colors = UniformColors((0.8, 0.6, 0.4))
    scene.renderables.add_mesh(v, faces, PrincipledBSDFMaterial(roughness=0.6), colors, smooth=True, tag="bunny")
    if plane:
        scene.renderables.add_plane_mesh(1.0, DiffuseMaterial(), UniformColors((0.6, 0.6, 0.6)), tag="ground")
    look_at_camera(scene, resolution, (0.25, -0.35, 0.2), (0, 0, 0.07), fov_x=np.deg2rad(35))
    if light == "area":
        scene.lights.add_area(
            "square", 0.3, strength=30.0, rotation_mode="look_at", rotation=(0, 0, 0), translation=(0.3, -0.2, 0.6)
        )
    else:
        scene.lights.add_sun(3.0, rotation_mode="eulerXYZ", rotation=(30, 20, 0))
    scene.lights.set_background_light(0.2)
    return scene


def textured_quad_scene(resolution: tuple[int, int] = (64, 64), faces_uv: bool = False) -> Scene:
    """A unit quad facing the camera with a 2x2 texture (top-left red, top-right green, bottom-left blue,
    bottom-right white), lit by a uniform background: checks UV orientation in every backend."""
    scene = Scene()
    tex = np.array([[[255, 0, 0], [0, 255, 0]], [[0, 0, 255], [255, 255, 255]]], dtype=np.uint8)
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], dtype=float)
    uv_v = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float)
    faces = np.array([[0, 1, 2, 3]])
    uv = FacesUV(uv_v[faces]) if faces_uv else VertexUV(uv_v)
    scene.renderables.add_mesh(v, faces, DiffuseMaterial(), TextureColors(tex, uv, interpolation="closest"), tag="quad")
    scene.set_orthographic_camera(resolution, ortho_scale=2.0, translation=(0, 0, 3.0))
    scene.lights.set_background_light(1.0)
    return scene


def pointcloud_scene(
    n: int = 2000, resolution: tuple[int, int] = (128, 128), seed: int = 0, point_size: float = 0.03
) -> Scene:
    """``n`` points on a unit sphere with per-point colours, lit by a sun and the background."""
    rng = np.random.default_rng(seed)
    p = rng.normal(size=(n, 3))
    p /= np.linalg.norm(p, axis=1, keepdims=True)
    scene = Scene()
    scene.renderables.add_pointcloud(
        p, DiffuseMaterial(), VertexColors(p * 0.5 + 0.5), point_size=point_size, tag="points"
    )
    look_at_camera(scene, resolution, (2.5, -2.5, 2.0), fov_x=np.deg2rad(40))
    scene.lights.add_sun(3.0, rotation_mode="eulerXYZ", rotation=(30, 20, 0))
    scene.lights.set_background_light(0.3)
    return scene


def primitives_scene(resolution: tuple[int, int] = (128, 96)) -> Scene:
    """Every primitive (cube, circle, cylinder, plane, sphere, ellipsoid, curve) in a row."""
    scene = Scene()
    r = scene.renderables
    grey = UniformColors((0.7, 0.7, 0.7))
    r.add_plane_mesh(6.0, DiffuseMaterial(), grey, tag="ground")
    r.add_cube_mesh(0.6, PlasticMaterial(), UniformColors((0.8, 0.2, 0.2)), translation=(-2.0, 0, 0.3), tag="cube")
    r.add_cylinder_mesh(
        0.3, 0.6, MetalMaterial(), UniformColors((0.9, 0.7, 0.3)), translation=(-1.0, 0, 0.3), tag="cylinder"
    )
    r.add_sphere_nurbs(0.3, DiffuseMaterial(), UniformColors((0.2, 0.6, 0.9)), translation=(0.0, 0, 0.3), tag="sphere")
    r.add_ellipsoid_nurbs(
        (0.2, 0.3, 0.4), DiffuseMaterial(), UniformColors((0.3, 0.8, 0.3)), translation=(1.0, 0, 0.4), tag="ellipsoid"
    )
    r.add_circle_mesh(
        0.3,
        DiffuseMaterial(),
        UniformColors((0.9, 0.9, 0.2)),
        translation=(2.0, 0, 0.3),
        rotation_mode="eulerXYZ",
        rotation=(90, 0, 0),
        tag="circle",
    )
    t = np.linspace(0, 1, 20)
    keys = np.stack([-2 + 4 * t, 0.8 + 0.2 * np.sin(6 * t), 0.2 + 0.4 * t], axis=1)
    r.add_curve_nurbs(keys, 0.05, DiffuseMaterial(), UniformColors((0.8, 0.3, 0.8)), tag="curve")
    look_at_camera(scene, resolution, (0.0, -6.0, 3.0), (0, 0, 0.3), fov_x=np.deg2rad(50))
    scene.lights.add_sun(3.0, rotation_mode="eulerXYZ", rotation=(35, 15, 0))
    scene.lights.set_background_light(0.3)
    return scene


def every_feature_scene(resolution: tuple[int, int] = (96, 72)) -> Scene:
    """One scene using (nearly) every IR feature: meshes with uniform/vertex/texture colours and per-face
    materials, a point cloud, all primitives, wireframe, emission, alpha, all light types."""
    scene = primitives_scene(resolution)
    r = scene.renderables
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 0.5, 1]], dtype=float)
    f = np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]])
    r.add_mesh(
        v * 0.5,
        f,
        [DiffuseMaterial(), GlossyBSDFMaterial(roughness=0.2)],
        [UniformColors((0.9, 0.1, 0.1)), UniformColors((0.1, 0.9, 0.1))],
        faces_material=[0, 1, 0, 1],
        translation=(-1.5, -1.2, 0),
        tag="pyramid",
    )
    r.add_mesh(
        v * 0.5,
        f,
        PlasticWireframeMaterial(wireframe_thickness=0.01),
        VertexColors(np.eye(5, 3) * 0.8 + 0.1),
        translation=(-0.5, -1.2, 0),
        tag="wire_pyramid",
    )
    tex = (np.indices((8, 8)).sum(axis=0) % 2 * 200 + 30).astype(np.uint8)
    rough = TextureMap(np.linspace(0, 1, 64).reshape(8, 8).astype(np.float32))
    nmap = NormalMap(np.dstack([np.full((8, 8), 0.5), np.full((8, 8), 0.5), np.ones((8, 8))]).astype(np.float32))
    uv = VertexUV(v[:, :2])
    r.add_mesh(
        v * 0.5,
        f,
        PrincipledBSDFMaterial(roughness_map=rough, normal_map=nmap, alpha=0.7),
        TextureColors(np.dstack([tex] * 3), uv),
        translation=(0.5, -1.2, 0),
        tag="textured",
    )
    r.add_sphere_nurbs(
        0.15,
        PrincipledBSDFMaterial(emission_color=(1, 0.5, 0.2), emission_strength=2.0),
        UniformColors((1, 1, 1)),
        translation=(1.5, -1.2, 0.3),
        tag="emitter",
    )
    rng = np.random.default_rng(1)
    pts = rng.uniform(-0.3, 0.3, size=(200, 3)) + [2.2, -1.2, 0.4]
    r.add_pointcloud(pts, DiffuseMaterial(), VertexColors(rng.uniform(size=(200, 3))), point_size=0.03, tag="points")
    lights = scene.lights
    lights.add_point(50.0, shadow_soft_size=0.1, translation=(0, -2, 2))
    lights.add_spot(100.0, translation=(2, -2, 3), rotation_mode="look_at", rotation=(0, 0, 0))
    lights.add_area("rectangle", (0.5, 0.3), 50.0, translation=(-2, -2, 2), rotation_mode="look_at", rotation=(0, 0, 0))
    lights.add_area("circle", 0.4, 30.0, translation=(0, 2, 2), rotation_mode="look_at", rotation=(0, 0, 0))
    return scene


# ---------------------------------------------------------------------------------------------------
# Hard cases: numerically awkward scenes every backend must render finitely and deterministically
# ---------------------------------------------------------------------------------------------------

_HC_RES = (32, 32)


def _hc_base(
    offset: Any = (0.0, 0.0, 0.0), scale: float = 1.0, resolution: tuple[int, int] = _HC_RES, lights: bool = True
) -> Scene:
    """A 1-unit cube and a sphere (times ``scale``) at ``offset``, camera 4 units away (times ``scale``)."""
    off = np.asarray(offset, dtype=np.float64)
    scene = Scene()
    scene.renderables.add_cube_mesh(
        0.8 * scale,
        DiffuseMaterial(),
        UniformColors((0.8, 0.3, 0.2)),
        translation=off + np.array([-0.5, 0, 0]) * scale,
        tag="cube",
    )
    scene.renderables.add_sphere_nurbs(
        0.4 * scale,
        DiffuseMaterial(),
        UniformColors((0.2, 0.5, 0.8)),
        translation=off + np.array([0.6, 0, 0]) * scale,
        tag="sphere",
    )
    cam_pos = off + np.array([0.0, -3.0, 2.0]) * scale
    scene.set_perspective_camera(
        resolution,
        fov_x=np.deg2rad(45),
        rotation_mode="look_at",
        rotation=off,
        translation=cam_pos,
        near=0.05 * scale,
        far=100.0 * scale,
    )
    if lights:
        scene.lights.add_sun(3.0, rotation_mode="eulerXYZ", rotation=(30, 20, 0))
        scene.lights.set_background_light(0.3)
    return scene


def _hc_mesh(vertices: Any, faces: Any, **kwargs: Any) -> Scene:
    scene = _hc_base()
    scene.renderables.clear()
    scene.renderables.add_mesh(
        np.asarray(vertices, float), faces, DiffuseMaterial(), UniformColors((0.7, 0.7, 0.7)), tag="mesh", **kwargs
    )
    return scene


def _hc_points(points: Any, size: float = 0.05) -> Scene:
    scene = _hc_base()
    scene.renderables.clear()
    pts = np.asarray(points, float)
    scene.renderables.add_pointcloud(
        pts, DiffuseMaterial(), VertexColors(np.full((len(pts), 3), 0.6)), point_size=size, tag="points"
    )
    return scene


def _hc_camera(scene: Scene, **kwargs: Any) -> Scene:
    old = scene.camera
    kwargs.setdefault("rotation_mode", "look_at")
    kwargs.setdefault("rotation", np.zeros(3))
    kwargs.setdefault("translation", old.translation)  # type: ignore[union-attr]
    kwargs.setdefault("resolution", _HC_RES)
    if "ortho_scale" in kwargs:
        scene.set_orthographic_camera(**kwargs)
    else:
        if not any(k in kwargs for k in ("fov_x", "fov_y", "focal_dist", "K")):
            kwargs["fov_x"] = np.deg2rad(45)
        scene.set_perspective_camera(**kwargs)
    return scene


def hard_cases(include_heavy: bool = False) -> dict[str, Any]:
    """Builders of numerically awkward scenes, by name -> zero-argument callable returning a Scene.

    Each is tiny (32x32) except the heavy ones (2M triangles, 1M points), which are included only with
    ``include_heavy``. ``HARD_CASE_REFERENCE`` says which cases must render like another one."""

    def rng() -> np.random.Generator:  # a fresh generator per call: every builder is deterministic
        return np.random.default_rng(7)

    tri = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    cases: dict[str, Any] = {
        "origin": lambda: _hc_base(),
        "far_from_origin_1e6": lambda: _hc_base(offset=(1e6, -1e6, 1e6)),
        "tiny_scale_1e-4": lambda: _hc_base(scale=1e-4),
        "world_vertices_origin": lambda: _hc_world_vertices((0.0, 0.0, 0.0)),
        "world_vertices_far_1e6": lambda: _hc_world_vertices((-3e6, 2e6, 1e6)),
        "huge_scale_1e4": lambda: _hc_base(scale=1e4),
        "look_straight_down": lambda: _hc_camera(_hc_base(), translation=(0, 0, 4.0)),
        "look_straight_up": lambda: _hc_camera(_hc_base(), translation=(0, 0, -4.0)),
        "camera_at_target": lambda: _hc_camera(_hc_base(), translation=(0, 0, 0.0)),
        "roll_180": lambda: _hc_camera(_hc_base(), rotation=(np.zeros(3), 180.0)),
        "unnormalised_quaternion": lambda: _hc_camera(
            _hc_base(), rotation_mode="quaternionWXYZ", rotation=(5.0, -5.0, 0.0, 0.0), translation=(0, 4.0, 0)
        ),
        "near_singular_rotmat": lambda: _hc_camera(
            _hc_base(),
            rotation_mode="rotmat",
            translation=(0, 4.0, 0),
            rotation=np.array([[1, 0, 0], [0, 0, 1], [0, -1, 0]]) + 1e-4 * rng().standard_normal((3, 3)),
        ),
        "euler_gimbal_lock": lambda: _hc_camera(
            _hc_base(), rotation_mode="eulerXYZ", rotation=(90, 90, 0), translation=(4.0, 0, 0)
        ),
        "fov_near_0": lambda: _hc_camera(_hc_base(), fov_x=1e-3, translation=(0, -4000.0, 0), near=1.0, far=1e4),
        "fov_near_180": lambda: _hc_camera(_hc_base(), fov_x=np.deg2rad(179.0)),
        "aspect_4096x16": lambda: _hc_camera(_hc_base(), resolution=(4096, 16), fov_x=np.deg2rad(120)),
        "principal_point_outside": lambda: _hc_camera(_hc_base(), K=[[30, 0, -20.0], [0, 30, 50.0], [0, 0, 1]]),
        "ortho_tiny": lambda: _hc_camera(_hc_base(), ortho_scale=1e-3),
        "ortho_huge": lambda: _hc_camera(_hc_base(), ortho_scale=1e4, far=1e5),
        "degenerate_triangles": lambda: _hc_mesh(
            [[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 2, 0], [2, 2, 0], [3, 3, 0]],
            [[0, 1, 2], [3, 4, 5], [0, 0, 0], [1, 1, 2]],
        ),
        "non_manifold_inconsistent": lambda: _hc_mesh(
            [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [0, -1, 0], [-1, 0, 0]],
            [[0, 1, 2], [0, 1, 3], [1, 0, 4], [0, 2, 5], [5, 2, 0]],
        ),
        "unreferenced_vertices": lambda: _hc_mesh(np.vstack([tri, rng().normal(size=(50, 3)) * 100]), [[0, 1, 2]]),
        "single_triangle": lambda: _hc_mesh(tri - 0.3, [[0, 1, 2]]),
        "coincident_points": lambda: _hc_points(np.zeros((100, 3))),
        "single_point": lambda: _hc_points(np.zeros((1, 3)), size=0.8),
        "colinear_points": lambda: _hc_points(np.stack([np.linspace(-1, 1, 50), np.zeros(50), np.zeros(50)], 1)),
        "colors_0_and_1": lambda: _hc_colors(),
        "texture_1x1_and_odd": lambda: _hc_textures(),
        "very_bright_light": lambda: _hc_light(1e6),
        "very_dim_light": lambda: _hc_light(1e-6),
        "light_inside_object": lambda: _hc_light(100.0, inside=True),
        "no_lights": lambda: _hc_base(lights=False),
        "empty_scene": lambda: _hc_empty(),
        # -- added by the robustness suite: more awkward inputs, several with a known answer -----------
        "smooth_zero_area_faces": lambda: _hc_mesh(
            [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [1, 1, 0], [0.5, 0.5, 0], [2, 0, 0]],
            [[0, 1, 2], [1, 3, 2], [3, 4, 4], [0, 5, 3], [1, 6, 6], [4, 4, 4]],
            smooth=True,
        ),
        "long_thin_triangles": lambda: _hc_mesh(
            [
                [-5e3, -0.2, 0],
                [5e3, -0.2, 0],
                [5e3, 0.2, 0],
                [-5e3, 0.2, 0],
                [0, 0, -1e3],
                [0, 1e-3, 1e3],
                [1e-3, 0, 1e3],
            ],
            [[0, 1, 2], [0, 2, 3], [4, 5, 6]],
            smooth=True,
        ),
        "huge_point_size": lambda: _hc_points(rng().normal(size=(5, 3)) * 0.3, size=3.0),
        "tiny_point_size": lambda: _hc_points(rng().normal(size=(200, 3)) * 0.5, size=1e-7),
        "near_far_sliver": lambda: _hc_camera(_hc_base(), near=3.5, far=3.7, translation=(0, -3.0, 2.0)),
        "objects_behind_camera": lambda: _hc_camera(
            _hc_base(), translation=(0, -3.0, 2.0), rotation=np.array([0.0, -10.0, 6.0])
        ),
        "camera_inside_object": lambda: _hc_inside_sphere(),
        "light_at_camera": lambda: _hc_light_at_camera(),
        "texture_1x1_faces_uv": lambda: _hc_textures(faces_uv=True),
        "vertex_colors_0_and_1": lambda: _hc_vertex_colors(),
        "resolution_1x1": lambda: _hc_camera(_hc_base(), resolution=(1, 1), fov_x=np.deg2rad(30)),
        "plane_depth_fx_fy_ratio_100": lambda: _hc_plane(K=[[2.0, 0, 15.5], [0, 200.0, 11.5], [0, 0, 1]]),
        "plane_depth_principal_point_outside": lambda: _hc_plane(K=[[30.0, 0, -20.0], [0, 30.0, 60.0], [0, 0, 1]]),
        "plane_depth_far_1e6": lambda: _hc_plane(offset=(1e6, 1e6, -1e6)),
        "markers_origin": lambda: _hc_markers((0.0, 0.0, 0.0)),
        "markers_far_1e6": lambda: _hc_markers((2e6, -1e6, 5e5)),
        "ortho_markers_far_1e5": lambda: _hc_markers((1e5, 1e5, 1e5), orthographic=True),
        "distant_point_light_hard_1e4": lambda: _hc_distant_light(1e4, 0.0),
        "distant_point_light_soft_1e3": lambda: _hc_distant_light(1e3, 0.25),
        "distant_point_light_soft_1e4": lambda: _hc_distant_light(1e4, 0.25),
        "resolution_percentage_2": lambda: _hc_percentage(2),
        "plane_depth_extreme_clip_range": lambda: _hc_plane(near=1e-6, far=1e9),
        "points_world_origin": lambda: _hc_world_points((0.0, 0.0, 0.0)),
        "points_world_far_1e6": lambda: _hc_world_points((1e6, 2e6, -1e6)),
        "curve_world_origin": lambda: _hc_world_curve((0.0, 0.0, 0.0)),
        "curve_world_far_1e6": lambda: _hc_world_curve((-1e6, 1e6, 1e6)),
        "tiny_scale_default_clip": lambda: _hc_default_clip(1e-4),
        "huge_scale_default_clip": lambda: _hc_default_clip(1e4),
        "zero_strength_lights": lambda: _hc_zero_lights(),
        "fully_transparent_materials": lambda: _hc_transparent(),
        "huge_emission_1e30": lambda: _hc_emission(1e30),
        "concave_polygon_faces": lambda: _hc_concave(),
        "empty_mesh": lambda: _hc_add_empty("mesh"),
        "empty_pointcloud": lambda: _hc_add_empty("points"),
        "huge_norm_quaternion": lambda: _hc_camera(
            _hc_base(), rotation_mode="quaternionWXYZ", rotation=(1e200, -1e200, 0.0, 0.0), translation=(0, 4.0, 0)
        ),
    }
    if include_heavy:
        cases["mesh_2M_triangles"] = lambda: _hc_big_mesh()
        cases["pointcloud_1M"] = lambda: _hc_points(rng().normal(size=(1_000_000, 3)) * 0.5, size=0.005)
    return cases


#: cases whose colour image must match another case's (same picture, different numbers)
HARD_CASE_REFERENCE = {
    "far_from_origin_1e6": "origin",
    "tiny_scale_1e-4": "origin",
    "huge_scale_1e4": "origin",
    "world_vertices_far_1e6": "world_vertices_origin",
    "markers_far_1e6": "markers_origin",
    "distant_point_light_soft_1e3": "distant_point_light_hard_1e4",
    "points_world_far_1e6": "points_world_origin",
    "curve_world_far_1e6": "curve_world_origin",
    "huge_norm_quaternion": "unnormalised_quaternion",
    "distant_point_light_soft_1e4": "distant_point_light_hard_1e4",
}


def _hc_world_vertices(offset: Any) -> Scene:
    """A torus mesh whose vertices are given in world coordinates around ``offset`` (identity pose), as
    scans and simulation output usually are."""
    off = np.asarray(offset, dtype=np.float64)
    t = torus(0.6, 0.25, 48, 24)
    scene = _hc_base(offset=off)
    scene.renderables.clear()
    scene.renderables.add_mesh(
        t.vertices + off, t.faces, DiffuseMaterial(), UniformColors((0.7, 0.5, 0.3)), smooth=True, tag="torus"
    )
    return scene


def _hc_colors() -> Scene:
    scene = _hc_base()
    scene.renderables["cube"].update_colors(UniformColors((0.0, 0.0, 0.0)))
    scene.renderables["sphere"].update_colors(UniformColors((1.0, 1.0, 1.0)))
    return scene


def _hc_textures(faces_uv: bool = False) -> Scene:
    scene = _hc_base()
    quad = np.array([[-1, 0, -1], [1, 0, -1], [1, 0, 1], [-1, 0, 1]], float)
    uv_v = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    uv: Any = FacesUV(uv_v[[[0, 1, 2, 3]]]) if faces_uv else VertexUV(uv_v)
    scene.renderables.add_mesh(
        quad * 0.5 + [0, -0.6, 0],
        [[0, 1, 2, 3]],
        DiffuseMaterial(),
        TextureColors(np.array([[[200, 30, 30]]], np.uint8), uv),
        tag="tex1x1",
    )
    odd = (np.random.default_rng(3).uniform(size=(5, 17, 3))).astype(np.float32)
    scene.renderables.add_mesh(
        quad * 0.4 + [0, -0.7, 1.0], [[0, 1, 2, 3]], DiffuseMaterial(), TextureColors(odd, uv), tag="tex_odd"
    )
    return scene


def _hc_light(strength: float, inside: bool = False) -> Scene:
    scene = _hc_base(lights=False)
    pos = scene.renderables["sphere"].translation if inside else np.array([0.0, -2.0, 2.0])
    scene.lights.add_point(strength, shadow_soft_size=0.0, translation=pos)
    return scene


def _hc_empty() -> Scene:
    scene = _hc_base()
    scene.renderables.clear()
    return scene


def _hc_big_mesh() -> Scene:
    m = uv_sphere(1.0, 1000, 1000)
    return _hc_mesh(m.vertices, m.faces)


#: what each hard case exercises (for docs/robustness.md)
HARD_CASE_DESCRIPTIONS = {
    "origin": "reference: a cube and a sphere at the origin",
    "far_from_origin_1e6": "the reference scene 1e6 m from the origin (core re-centring)",
    "tiny_scale_1e-4": "the reference scene scaled by 1e-4 (near/far scaled too)",
    "world_vertices_origin": "a torus given in world-coordinate vertices at the origin",
    "world_vertices_far_1e6": "the torus with vertices ~3e6 m from the origin (vertex re-centring)",
    "huge_scale_1e4": "the reference scene scaled by 1e4",
    "look_straight_down": "look_at with the view direction parallel to the up axis (down)",
    "look_straight_up": "look_at with the view direction parallel to the up axis (up)",
    "camera_at_target": "look_at with the camera at its target",
    "roll_180": "look_at with a 180 degree roll",
    "unnormalised_quaternion": "camera rotation from a quaternion of norm 7 (looking at the objects)",
    "near_singular_rotmat": "camera rotation matrix with 1e-4 noise (re-orthonormalised; looking at the objects)",
    "euler_gimbal_lock": "Euler XYZ (90, 90, 0): gimbal lock",
    "fov_near_0": "fov 1e-3 rad from 4 km away",
    "fov_near_180": "fov 179 degrees",
    "aspect_4096x16": "4096x16 image",
    "principal_point_outside": "principal point outside the image",
    "ortho_tiny": "orthographic scale 1e-3",
    "ortho_huge": "orthographic scale 1e4",
    "degenerate_triangles": "zero-area and repeated-vertex triangles",
    "non_manifold_inconsistent": "non-manifold edges, inconsistent winding",
    "unreferenced_vertices": "one triangle and 50 unreferenced far vertices",
    "single_triangle": "a mesh of one triangle",
    "coincident_points": "100 coincident points",
    "single_point": "a point cloud of one point",
    "colinear_points": "50 colinear points",
    "colors_0_and_1": "uniform colours exactly 0 and exactly 1",
    "texture_1x1_and_odd": "1x1 and 5x17 textures (VertexUV)",
    "very_bright_light": "a 1e6 W point light",
    "very_dim_light": "a 1e-6 W point light",
    "light_inside_object": "a point light inside the sphere",
    "no_lights": "no lights: warning and a black image",
    "empty_scene": "no renderables: empty depth/instance, zero alpha",
    "smooth_zero_area_faces": "smooth shading with zero-area faces (normals must not be NaN)",
    "long_thin_triangles": "a 0.4 m strip of two 1e4 m long slivers (aspect 2.5e4), a 1e-3 m wide needle",
    "huge_point_size": "points 3 m in diameter (larger than the scene)",
    "tiny_point_size": "points 1e-7 m in diameter",
    "near_far_sliver": "near 3.5, far 3.7: only a thin depth slab is visible",
    "objects_behind_camera": "every object behind the camera: empty image",
    "camera_inside_object": "camera inside a closed sphere: every pixel hits it",
    "light_at_camera": "a point light at the camera position",
    "texture_1x1_faces_uv": "1x1 and odd textures with FacesUV",
    "vertex_colors_0_and_1": "vertex colours exactly 0 and exactly 1",
    "resolution_1x1": "a 1x1 image",
    "plane_depth_fx_fy_ratio_100": "fx/fy = 1/100 (non-square pixels): plane depth known",
    "plane_depth_principal_point_outside": "principal point outside the image: plane depth known",
    "plane_depth_far_1e6": "a tilted plane 1e6 m from the origin: plane depth known",
    "markers_origin": "camera self-test: marker sphere centroids at their projected pixels",
    "markers_far_1e6": "the marker scene 2e6 m from the origin: markers at their projected pixels",
    "ortho_markers_far_1e5": "orthographic marker scene 1e5 m from the origin",
    "distant_point_light_hard_1e4": "a point light (radius 0) 1e4 m away, power x d^2: reference irradiance",
    "distant_point_light_soft_1e3": "the default 0.25 m point light 1e3 m away: must light like the hard one",
    "distant_point_light_soft_1e4": "the default 0.25 m point light 1e4 m away: must light like the hard one",
    "resolution_percentage_2": "32x32 at resolution_percentage 2: a 1x1 image",
    "tiny_scale_default_clip": "the 1e-4 scene with the default near 0.1: reported (warning), empty image",
    "huge_scale_default_clip": "the 1e4 scene with the default far 100: reported (warning), empty image",
    "zero_strength_lights": "point and sun lights of 0 W, background of strength 0: black, not NaN",
    "fully_transparent_materials": "material alpha 0 and 1e-6, a texture with alpha 0 everywhere",
    "huge_emission_1e30": "an emitter of strength 1e30 (float32 max is 3.4e38)",
    "concave_polygon_faces": "an L-shaped hexagon face (one reflex corner) seen from above: silhouette known",
    "huge_norm_quaternion": "camera rotation from a quaternion of norm 1.4e200 (|q|^2 overflows float64)",
    "empty_mesh": "the reference scene plus a mesh with 5 vertices and no faces",
    "empty_pointcloud": "the reference scene plus a point cloud of 0 points",
    "points_world_origin": "a 300-point cloud in world coordinates at the origin",
    "points_world_far_1e6": "the point cloud in world coordinates ~2e6 m from the origin (vertex re-centring)",
    "curve_world_origin": "a curve with world-coordinate keypoints at the origin",
    "curve_world_far_1e6": "the curve with keypoints ~1e6 m from the origin (keypoint re-centring)",
    "plane_depth_extreme_clip_range": "near 1e-6, far 1e9 (depth-buffer precision): plane depth known",
    "mesh_2M_triangles": "a 2M-triangle sphere (slow)",
    "pointcloud_1M": "a 1M-point cloud (slow)",
}


def _hc_inside_sphere() -> Scene:
    scene = _hc_base()
    scene.renderables.add_sphere_nurbs(
        10.0, DiffuseMaterial(), UniformColors((0.5, 0.5, 0.5)), translation=(0, 0, 0), tag="enclosure"
    )
    scene.lights.add_point(100.0, shadow_soft_size=0.0, translation=(0, 0, 5.0))
    return scene


def _hc_light_at_camera() -> Scene:
    scene = _hc_base(lights=False)
    scene.lights.add_point(30.0, shadow_soft_size=0.0, translation=scene.camera.translation)  # type: ignore[union-attr]
    return scene


def _hc_vertex_colors() -> Scene:
    scene = _hc_base()
    scene.renderables.clear()
    m = uv_sphere(0.8, 16, 8)
    c = (m.vertices[:, 2:3] > 0).astype(float) * np.ones((1, 3))
    scene.renderables.add_mesh(m.vertices, m.faces, DiffuseMaterial(), VertexColors(c), smooth=True, tag="mesh")
    return scene


def _hc_plane(offset: Any = (0.0, 0.0, 0.0), K: Any = None, near: float = 0.05, far: float = 100.0) -> Scene:
    """depth_plane_scene (32x24, camera 3 m from a 30-degree plane) moved by ``offset``, optionally with
    intrinsics ``K``; :func:`expected_plane_depth` gives the answer."""
    off = np.asarray(offset, dtype=np.float64)
    scene = Scene()
    cam = dict(translation=off + [0, 0, 3.0], near=near, far=far)
    if K is None:
        scene.set_perspective_camera((32, 24), fov_x=np.deg2rad(50), **cam)  # type: ignore[arg-type]
    else:
        scene.set_perspective_camera((32, 24), K=np.asarray(K, float), **cam)  # type: ignore[arg-type]
    scene.renderables.add_plane_mesh(
        200.0,
        DiffuseMaterial(),
        UniformColors((0.5, 0.5, 0.5)),
        rotation_mode="eulerXYZ",
        rotation=(30.0, 0, 0),
        translation=off,
        tag="plane",
    )
    scene.lights.set_background_light(1.0)
    return scene


def _hc_markers(offset: Any, orthographic: bool = False) -> Scene:
    """marker_scene (80x60) moved by ``offset``; the markers ("marker_i") project to known pixels."""
    off = np.asarray(offset, dtype=np.float64)
    scene, _ = marker_scene((80, 60), fx=75.0, center=(41.3, 28.6), radius=0.2, orthographic=orthographic)
    for r in scene.renderables:
        r.translation = r.translation + off
    scene.camera.translation = scene.camera.translation + off  # type: ignore[union-attr]
    return scene


def _hc_distant_light(distance: float, radius: float) -> Scene:
    """The reference scene lit only by a point light ``distance`` metres away (power scaled by distance^2,
    so the irradiance at the objects is the same for every distance: ~8 W/m^2)."""
    scene = _hc_base(lights=False)
    direction = np.array([0.3, -1.0, 1.0]) / np.linalg.norm([0.3, -1.0, 1.0])
    scene.lights.add_point(
        100.0 * distance**2, shadow_soft_size=radius, translation=direction * distance, tag="distant"
    )
    return scene


def _hc_percentage(percentage: int) -> Scene:
    scene = _hc_base()
    scene.camera.resolution_percentage = percentage  # type: ignore[union-attr]
    return scene


def _hc_world_points(offset: Any) -> Scene:
    off = np.asarray(offset, dtype=np.float64)
    pts = np.random.default_rng(11).normal(size=(300, 3)) * 0.5
    scene = _hc_base(offset=off)
    scene.renderables.clear()
    scene.renderables.add_pointcloud(
        pts + off, DiffuseMaterial(), VertexColors(np.clip(pts * 0.5 + 0.5, 0, 1)), point_size=0.08, tag="points"
    )
    return scene


def _hc_world_curve(offset: Any) -> Scene:
    off = np.asarray(offset, dtype=np.float64)
    t = np.linspace(0.0, 1.0, 12)
    keys = np.stack([2.0 * t - 1.0, 0.3 * np.cos(5 * t), 0.5 * np.sin(6 * t)], axis=1)
    scene = _hc_base(offset=off)
    scene.renderables.clear()
    scene.renderables.add_curve_nurbs(keys + off, 0.08, DiffuseMaterial(), UniformColors((0.3, 0.7, 0.4)), tag="curve")
    return scene


def _hc_default_clip(scale: float) -> Scene:
    """The reference scene at ``scale`` with the camera's default near/far (0.1, 100): everything is
    clipped, which :func:`blendify_core.pipeline.render` reports with a warning naming near or far."""
    scene = _hc_base(scale=scale)
    cam = scene.camera
    if cam is None:
        raise InvalidSceneError("_hc_base: the reference scene has no camera")
    cam.far = max(cam.far, 100.0)  # order: near < far at every step
    cam.near = 0.1
    cam.far = 100.0
    return scene


def _hc_zero_lights() -> Scene:
    scene = _hc_base(lights=False)
    scene.lights.add_point(0.0, translation=(0, -2.0, 2.0))
    scene.lights.add_sun(0.0)
    scene.lights.set_background_light(0.0)
    return scene


def _hc_transparent() -> Scene:
    scene = _hc_base()
    scene.renderables["sphere"].update_material(PrincipledBSDFMaterial(alpha=0.0))
    scene.renderables["cube"].update_material(PrincipledBSDFMaterial(alpha=1e-6))
    quad = np.array([[-1, 0, -1], [1, 0, -1], [1, 0, 1], [-1, 0, 1]], float) * 0.5 + [0, -0.6, 0]
    tex = np.zeros((4, 4, 4), np.uint8)
    tex[..., 0] = 255
    uv = VertexUV([[0, 0], [1, 0], [1, 1], [0, 1]])
    scene.renderables.add_mesh(quad, [[0, 1, 2, 3]], DiffuseMaterial(), TextureColors(tex, uv), tag="clear_quad")
    return scene


def _hc_emission(strength: float) -> Scene:
    scene = _hc_base()
    scene.renderables["sphere"].update_material(
        PrincipledBSDFMaterial(emission_color=(1.0, 1.0, 1.0), emission_strength=strength)
    )
    return scene


#: the L-shaped hexagon of ``concave_polygon_faces`` (x, y), area 3, listed from a corner whose fan leaks
HC_L_SHAPE = np.array([[1, 2], [0, 2], [0, 0], [2, 0], [2, 1], [1, 1]], float) - 1.0


def _hc_concave() -> Scene:
    scene = Scene()
    scene.renderables.add_mesh(
        np.c_[HC_L_SHAPE, np.zeros(6)], [list(range(6))], DiffuseMaterial(), UniformColors((0.6, 0.6, 0.6)), tag="L"
    )
    scene.set_orthographic_camera(_HC_RES, ortho_scale=2.5, translation=(0, 0, 3.0), near=0.1, far=10)
    scene.lights.set_background_light(1.0)
    return scene


def _hc_add_empty(kind: str) -> Scene:
    scene = _hc_base()
    grey = UniformColors((0.5, 0.5, 0.5))
    if kind == "mesh":
        verts = np.random.default_rng(5).uniform(size=(5, 3))
        scene.renderables.add_mesh(verts, np.zeros((0, 3), int), DiffuseMaterial(), grey, tag="empty")
    else:
        scene.renderables.add_pointcloud(np.zeros((0, 3)), DiffuseMaterial(), grey, tag="empty")
    return scene


#: the physical defects :func:`calibration_scene` can inject into one side of a comparison
CALIBRATION_DEFECTS = ("shift_half_px", "wrong_colour_space", "mirrored_texture")


def calibration_scene(index: int, resolution: tuple[int, int] = (64, 48), defect: str | None = None) -> Scene:
    """A random Lambertian scene (seeded by ``index``) for calibrating the noise-aware verdict: a ground
    plane with an asymmetric sRGB texture, a textured upright panel, 2-4 spheres and cubes with sRGB
    colours, one lighting setup (sun, point, square area light, sun + sky, or sky only) and a look-at
    camera. ``defect`` renders the same scene wrongly: "shift_half_px" (principal point moved by half a
    pixel), "wrong_colour_space" (every colour and texture read as linear instead of sRGB),
    "mirrored_texture" (both textures flipped left-right)."""
    if defect is not None and defect not in CALIBRATION_DEFECTS:
        raise InvalidSceneError(f"defect: expected None or one of {CALIBRATION_DEFECTS}, got {defect!r}")
    rng = np.random.default_rng(index)
    space = "linear" if defect == "wrong_colour_space" else "srgb"
    scene = Scene()

    def texture(cells: int) -> np.ndarray:
        two = rng.uniform(0.15, 0.95, (2, 3))
        pick = rng.random((cells, cells)) < 0.5
        img = np.where(pick[..., None], two[0], two[1])
        img = np.repeat(np.repeat(img, 64 // cells, axis=0), 64 // cells, axis=1)
        img[: 64 // cells, :] = rng.uniform(0.15, 0.95, 3)  # a stripe: never symmetric
        if defect == "mirrored_texture":
            img = img[:, ::-1]
        return np.round(img * 255).astype(np.uint8)

    quad = np.array([[0, 1, 2, 3]])
    uv = VertexUV(np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float))
    g = 3.0
    ground = np.array([[-g, -g, 0], [g, -g, 0], [g, g, 0], [-g, g, 0]], dtype=float)
    scene.renderables.add_mesh(
        ground,
        quad,
        DiffuseMaterial(),
        TextureColors(texture(int(rng.choice([4, 8]))), uv, color_space=space),
        tag="ground",
    )
    panel = np.array([[-1.2, 1.5, 0], [1.2, 1.5, 0], [1.2, 1.5, 1.6], [-1.2, 1.5, 1.6]], dtype=float)
    scene.renderables.add_mesh(
        panel, quad, DiffuseMaterial(), TextureColors(texture(8), uv, color_space=space), tag="panel"
    )
    for j in range(int(rng.integers(2, 5))):
        colour = UniformColors(tuple(rng.uniform(0.1, 0.9, 3)), color_space=space)
        pos = (rng.uniform(-1.5, 1.5), rng.uniform(-1.2, 0.8), 0.0)
        size = rng.uniform(0.25, 0.5)
        if rng.random() < 0.5:
            scene.renderables.add_sphere_nurbs(
                size, DiffuseMaterial(), colour, translation=(pos[0], pos[1], size), tag=f"sphere{j}"
            )
        else:
            scene.renderables.add_cube_mesh(
                size,
                DiffuseMaterial(),
                colour,
                translation=(pos[0], pos[1], size / 2),
                rotation_mode="eulerXYZ",
                rotation=(0, 0, rng.uniform(0, 90)),
                tag=f"cube{j}",
            )
    light = ("sun", "point", "area", "sun_sky", "sky")[index % 5]
    if light in ("sun", "sun_sky"):
        scene.lights.add_sun(3.0, rotation_mode="eulerXYZ", rotation=(rng.uniform(20, 50), 0, rng.uniform(-60, 60)))
    if light == "point":
        scene.lights.add_point(strength=300.0, translation=(rng.uniform(-2, 2), rng.uniform(-3, -1), 3.0))
    if light == "area":
        scene.lights.add_area("square", 1.0, strength=300.0, translation=(rng.uniform(-1, 1), -1.0, 3.0))
    if light in ("sun_sky", "sky"):
        scene.lights.set_background_light(0.5 if light == "sun_sky" else 1.5)
    width, height = resolution
    az = np.deg2rad(rng.uniform(-35, 35))
    position = (6.0 * np.sin(az), -6.0 * np.cos(az), rng.uniform(2.5, 4.0))
    center = (width / 2 + 0.5, height / 2) if defect == "shift_half_px" else None
    look_at_camera(scene, resolution, position, (0, 0, 0.5), fov_x=np.deg2rad(45), center=center)
    return scene


# ---------------------------------------------------------------------------------------------------
# image files at full precision (written with numpy alone, so a test never depends on the reader it checks)
# ---------------------------------------------------------------------------------------------------


def rgbe_encode(rgb: AnyArray) -> AnyArray:
    """(H, W, 4) uint8 RGBE of (H, W, 3) non-negative floats (Ward's encoding: mantissas truncated)."""
    rgb = np.asarray(rgb, dtype=np.float64)
    m = rgb.max(axis=-1)
    frac, exp = np.frexp(m)  # m = frac * 2^exp, frac in [0.5, 1)
    scale = np.where(m > 1e-32, 256.0 / np.ldexp(1.0, exp), 0.0)
    out = np.zeros(rgb.shape[:-1] + (4,), dtype=np.uint8)
    out[..., :3] = np.clip(np.floor(rgb * scale[..., None]), 0, 255).astype(np.uint8)
    out[..., 3] = np.where(m > 1e-32, exp + 128, 0).astype(np.uint8)
    return out


def _rle_channel(values: AnyArray) -> bytes:
    out = bytearray()
    i, n = 0, len(values)
    while i < n:
        j = i
        while j < n and j - i < 127 and values[j] == values[i]:
            j += 1
        if j - i >= 3:  # a run
            out += bytes([128 + (j - i), int(values[i])])
            i = j
            continue
        j = i
        while j < n and j - i < 128 and not (j + 2 < n and values[j] == values[j + 1] == values[j + 2]):
            j += 1
        j = max(j, i + 1)
        out += bytes([j - i]) + bytes(values[i:j].tolist())
        i = j
    return bytes(out)


def write_radiance_hdr(path: str | Path, rgb: AnyArray, rle: bool = True) -> Path:
    """Write (H, W, 3) floats as a Radiance file (run-length encoded scanlines, or flat), row 0 = top."""
    rgbe = rgbe_encode(rgb)
    h, w = rgbe.shape[:2]
    body = bytearray(b"#?RADIANCE\n# written by blendify_core.testing_images\nFORMAT=32-bit_rle_rgbe\n\n")
    body += f"-Y {h} +X {w}\n".encode()
    for y in range(h):
        if rle and 8 <= w < 32768:
            body += bytes([2, 2, w >> 8, w & 255])
            for c in range(4):
                body += _rle_channel(rgbe[y, :, c])
        else:
            body += rgbe[y].tobytes()
    p = Path(path)
    p.write_bytes(bytes(body))
    return p


def _filter_row(kind: int, row: AnyArray, prev: AnyArray, bpp: int) -> AnyArray:
    """PNG filter ``kind`` applied to one row of bytes (int arrays), ``prev`` the unfiltered row above."""
    left = np.concatenate([np.zeros(bpp, np.int32), row[:-bpp]])
    up_left = np.concatenate([np.zeros(bpp, np.int32), prev[:-bpp]])
    if kind == 0:
        pred = np.zeros_like(row)
    elif kind == 1:
        pred = left
    elif kind == 2:
        pred = prev
    elif kind == 3:
        pred = (left + prev) >> 1
    else:
        pa, pb, pc = np.abs(prev - up_left), np.abs(left - up_left), np.abs(left + prev - 2 * up_left)
        pred = np.where((pa <= pb) & (pa <= pc), left, np.where(pb <= pc, prev, up_left))
    return (row - pred) & 255


def write_png16(path: str | Path, values: AnyArray, filters: tuple[int, ...] = (0,)) -> Path:
    """Write (H, W, C) uint16 values (C = 1, 2, 3, 4) as a 16-bit PNG; row y uses filter
    ``filters[y % len(filters)]`` (0 None, 1 Sub, 2 Up, 3 Average, 4 Paeth)."""
    arr = np.asarray(values, dtype=np.uint16)
    if arr.ndim == 2:
        arr = arr[..., None]
    h, w, c = arr.shape
    ctype = {1: 0, 2: 4, 3: 2, 4: 6}[c]
    bpp = 2 * c
    rows = np.frombuffer(arr.astype(">u2").tobytes(), dtype=np.uint8).reshape(h, w * bpp).astype(np.int32)
    raw = bytearray()
    prev = np.zeros(w * bpp, np.int32)
    for y in range(h):
        kind = filters[y % len(filters)]
        raw.append(kind)
        raw += _filter_row(kind, rows[y], prev, bpp).astype(np.uint8).tobytes()
        prev = rows[y]

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    p = Path(path)
    p.write_bytes(
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 16, ctype, 0, 0, 0))
        + chunk(b"IDAT", zlib.compress(bytes(raw)))
        + chunk(b"IEND", b"")
    )
    return p


# -- realistic benchmark scenes (accuracy_vs_time at realistic size) ---------------------------------------
def _inward_quad(corners: Any, facing: Any) -> AnyArray:
    """Four corners ordered so that the quad's normal points along ``facing``."""
    c = np.asarray(corners, dtype=np.float64)
    n = np.cross(c[1] - c[0], c[2] - c[0])
    return c if float(n @ np.asarray(facing, dtype=np.float64)) > 0 else c[::-1].copy()


def _box_mesh(centre: Any, half: Any, angle_deg: float) -> tuple[AnyArray, AnyArray]:
    """An axis-aligned box of half extents ``half`` turned by ``angle_deg`` about +Z, centred at ``centre``:
    (vertices, outward quads)."""
    corners = np.array([[x, y, z] for z in (-1, 1) for y in (-1, 1) for x in (-1, 1)], dtype=np.float64)
    a = np.deg2rad(angle_deg)
    rot = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    v = (corners * np.asarray(half, dtype=np.float64)) @ rot.T + np.asarray(centre, dtype=np.float64)
    faces = np.array([[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]])
    return v, faces


def cornell_room_scene(resolution: tuple[int, int] = (64, 64), light_strength: float = 15.0) -> Scene:
    """A closed Cornell-style room (2 x 2 x 2 m, all six walls facing inward: red on the left, green on the
    right, white elsewhere, the wall behind the camera included), a tall and a short white box, one square
    area light under the ceiling and no background light. Lambertian throughout; most of what the camera
    sees is lit indirectly (the ceiling only so): the global-illumination case of the benchmarks."""
    scene = Scene()
    white, red, green = (0.75, 0.75, 0.75), (0.65, 0.06, 0.05), (0.12, 0.45, 0.10)
    lo, hi = (-1.0, -1.0, 0.0), (1.0, 1.0, 2.0)
    x0, y0, z0 = lo
    x1, y1, z1 = hi
    walls = {
        "floor": ([(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0)], (0, 0, 1), white),
        "ceiling": ([(x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)], (0, 0, -1), white),
        "back_wall": ([(x0, y1, z0), (x1, y1, z0), (x1, y1, z1), (x0, y1, z1)], (0, -1, 0), white),
        "front_wall": ([(x0, y0, z0), (x1, y0, z0), (x1, y0, z1), (x0, y0, z1)], (0, 1, 0), white),
        "red_wall": ([(x0, y0, z0), (x0, y1, z0), (x0, y1, z1), (x0, y0, z1)], (1, 0, 0), red),
        "green_wall": ([(x1, y0, z0), (x1, y1, z0), (x1, y1, z1), (x1, y0, z1)], (-1, 0, 0), green),
    }
    for tag, (corners, facing, colour) in walls.items():
        scene.renderables.add_mesh(
            _inward_quad(corners, facing),
            np.array([[0, 1, 2, 3]]),
            DiffuseMaterial(),
            UniformColors(colour, color_space="linear"),
            tag=tag,
        )
    for tag, centre, half, angle in (
        ("tall_box", (-0.4, 0.45, 0.6), (0.28, 0.28, 0.6), 18.0),
        ("short_box", (0.42, -0.05, 0.28), (0.28, 0.28, 0.28), -17.0),
    ):
        v, f = _box_mesh(centre, half, angle)
        scene.renderables.add_mesh(v, f, DiffuseMaterial(), UniformColors(white, color_space="linear"), tag=tag)
    scene.lights.add_area("square", 0.5, strength=light_strength, translation=(0.0, 0.0, 1.98), tag="ceiling_light")
    look_at_camera(scene, resolution, (0.0, -0.95, 1.0), (0.0, 1.0, 0.95), fov_x=np.deg2rad(70.0), near=0.01)
    return scene


def textured_scan_scene(resolution: tuple[int, int] = (64, 64)) -> Scene:
    """A textured scan on a table: the fuze bottle (``tests/data/fuze.obj`` with its photographed texture)
    standing on a light-grey diffuse table top, a warm rectangular key light above one side, a dim sky,
    seen from a little above at close range. Textured, soft shadows, some indirect light from the table."""
    scene = Scene()
    scene.renderables.add_trimesh(str(data_path("fuze.obj")), translation=(0.0, 0.0, -0.004016), tag="fuze")
    scene.renderables.add_plane_mesh(
        1.5, DiffuseMaterial(), UniformColors((0.55, 0.5, 0.45)), translation=(0.0, 0.0, 0.0), tag="table"
    )
    scene.lights.add_area(
        "rectangle",
        (0.4, 0.25),
        strength=25.0,
        color=(1.0, 0.92, 0.8),
        rotation_mode="look_at",
        rotation=(0.0, 0.0, 0.08),
        translation=(-0.35, -0.25, 0.5),
        tag="key",
    )
    scene.lights.set_background_light(0.25)
    look_at_camera(scene, resolution, (0.22, -0.3, 0.2), (0.0, 0.0, 0.1), fov_x=np.deg2rad(45.0))
    return scene


def pointcloud_catcher_scene(
    resolution: tuple[int, int] = (64, 64), n: int = 6000, seed: int = 0, point_size: float = 0.005
) -> Scene:
    """A scanned point cloud standing on a shadow catcher: ``n`` vertices of the Stanford bunny
    (``tests/data/bunny.ply``, +Z up, resting on z = 0) as spheres coloured by height, on a shadow-catcher
    plane (invisible except for the shadows on it), lit by a sun and the background."""
    import trimesh

    tm: Any = trimesh.load(data_path("bunny.ply"), process=False)
    v = np.asarray(tm.vertices, dtype=np.float64)
    v = v[:, [0, 2, 1]] * np.array([1, -1, 1])  # +Y up -> +Z up (right-handed)
    v -= [v[:, 0].mean(), v[:, 1].mean(), v[:, 2].min()]
    rng = np.random.default_rng(seed)
    pts = v[rng.choice(len(v), size=min(n, len(v)), replace=False)]
    h = (pts[:, 2] - pts[:, 2].min()) / max(float(np.ptp(pts[:, 2])), 1e-9)
    colours = np.stack([0.85 - 0.5 * h, 0.35 + 0.3 * h, 0.25 + 0.55 * h], axis=1)
    scene = Scene()
    scene.renderables.add_pointcloud(pts, DiffuseMaterial(), VertexColors(colours), point_size=point_size, tag="points")
    scene.renderables.add_plane_mesh(
        1.0, DiffuseMaterial(), UniformColors((1.0, 1.0, 1.0)), shadow_catcher=True, tag="catcher"
    )
    scene.lights.add_sun(3.0, rotation_mode="eulerXYZ", rotation=(35, 25, 0))
    scene.lights.set_background_light(0.3)
    look_at_camera(scene, resolution, (0.25, -0.35, 0.2), (0.0, 0.0, 0.06), fov_x=np.deg2rad(35.0))
    return scene
