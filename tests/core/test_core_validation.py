"""Table of bad inputs: each raises InvalidSceneError (a ValueError and a BlendifyError) at the call
that received it, with a message naming the argument. Nothing may escape as a bare Python error."""

from __future__ import annotations

import numpy as np
import pytest

import blendify_core as bf
from blendify_core.errors import BlendifyError, InvalidSceneError
from blendify_core.pipeline.result import RenderResult
from blendify_core.pipeline.settings import resolve_settings

M = bf.PrincipledBSDFMaterial
U = bf.UniformColors
V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=float)
QUADS = np.array([[0, 1, 2, 3]])
TRIS = np.array([[0, 1, 2], [0, 2, 3]])


def mesh(**kw):
    args = dict(vertices=V, faces=TRIS, material=M(), colors=U((0.5, 0.5, 0.5)))
    args.update(kw)
    return bf.Scene().renderables.add_mesh(**args)


def persp(**kw):
    args = dict(resolution=(64, 48), fov_x=1.0)
    args.update(kw)
    return bf.Scene().set_perspective_camera(**args)


def scene_with_camera():
    s = bf.Scene()
    s.renderables.add_sphere_nurbs(1.0, M(), U((1, 1, 1)))
    s.lights.add_point()
    s.set_perspective_camera((16, 16), fov_x=1.0, translation=(0, 0, 5))
    return s


def render(**kw):
    return bf.render(scene_with_camera(), **kw)


def dup_renderable_tag():
    s = bf.Scene()
    s.renderables.add_sphere_nurbs(1.0, M(), U((1, 1, 1)), tag="a")
    s.renderables.add_cube_mesh(1.0, M(), U((1, 1, 1)), tag="a")


def dup_light_tag():
    s = bf.Scene()
    s.lights.add_point(tag="key")
    s.lights.add_sun(tag="key")


def set_material_attr(name, value, cls=M):
    mat = cls()
    setattr(mat, name, value)


def rr():
    return RenderResult(rgba=np.zeros((4, 4, 4), np.float32))


def set_attr(obj, name, value):
    setattr(obj, name, value)


REFLECTION = np.diag([1.0, 1.0, -1.0])
SKEWED_K = np.array([[100.0, 2.0, 32], [0, 100, 24], [0, 0, 1]])

# (id, callable, words the message must contain)
BAD_INPUTS = [
    # -- mesh geometry ------------------------------------------------------------------------------
    ("vertices-wrong-shape", lambda: mesh(vertices=V[:, :2]), "vertices"),
    ("vertices-1d", lambda: mesh(vertices=np.zeros(12)), "vertices"),
    ("vertices-strings", lambda: mesh(vertices=[["a", "b", "c"]] * 4), "vertices"),
    ("vertices-complex", lambda: mesh(vertices=V + 1j), "vertices"),
    ("vertices-bool", lambda: mesh(vertices=V > 0), "vertices"),
    ("vertices-nan", lambda: mesh(vertices=np.where(V == 1, np.nan, V)), "vertices"),
    ("vertices-inf", lambda: mesh(vertices=np.where(V == 1, np.inf, V)), "vertices"),
    ("vertices-none", lambda: mesh(vertices=None), "vertices"),
    ("faces-out-of-range", lambda: mesh(faces=[[0, 1, 4]]), "faces"),
    ("faces-negative", lambda: mesh(faces=[[0, -1, 2]]), "faces"),
    ("faces-non-integer-floats", lambda: mesh(faces=[[0, 1, 2.5]]), "faces"),
    ("faces-two-columns", lambda: mesh(faces=[[0, 1], [1, 2]]), "faces"),
    ("faces-ragged-too-small", lambda: mesh(faces=[[0, 1, 2], [2, 3]]), "faces[1]"),
    ("faces-ragged-out-of-range", lambda: mesh(faces=[[0, 1, 2, 3], [2, 3, 9]]), "faces[1]"),
    ("faces-string", lambda: mesh(faces="0 1 2"), "faces"),
    ("faces-3d-array", lambda: mesh(faces=np.zeros((1, 3, 1), int)), "faces"),
    # -- colours --------------------------------------------------------------------------------------
    ("uniform-color-above-1", lambda: U((1.5, 0, 0)), "uniform_color"),
    ("uniform-color-negative", lambda: U((-0.1, 0, 0)), "uniform_color"),
    ("uniform-color-int-255", lambda: U((255, 0, 0)), "uniform_color"),
    ("uniform-color-two-values", lambda: U((0.5, 0.5)), "uniform_color"),
    ("uniform-color-nan", lambda: U((np.nan, 0, 0)), "uniform_color"),
    ("vertex-colors-above-1", lambda: bf.VertexColors(np.full((4, 3), 1.2)), "vertex_colors"),
    ("vertex-colors-int64-255", lambda: bf.VertexColors(np.full((4, 3), 255, np.int64)), "vertex_colors"),
    ("vertex-colors-5-channels", lambda: bf.VertexColors(np.zeros((4, 5))), "vertex_colors"),
    ("vertex-colors-count-mismatch", lambda: mesh(colors=bf.VertexColors(np.zeros((3, 3)))), "colors"),
    ("color-space-unknown", lambda: U((1, 1, 1), color_space="rgb"), "color_space"),
    ("colors-not-a-colour-source", lambda: mesh(colors=(0.5, 0.5, 0.5)), "colors"),
    ("material-not-a-material", lambda: mesh(material="plastic"), "material"),
    (
        "texture-on-pointcloud",
        lambda: bf.Scene().renderables.add_pointcloud(
            V, M(), bf.TextureColors(np.zeros((2, 2, 3), np.uint8), bf.VertexUV(V[:, :2]))
        ),
        "colors",
    ),
    (
        "vertex-colors-on-primitive",
        lambda: bf.Scene().renderables.add_cube_mesh(1.0, M(), bf.VertexColors(np.zeros((8, 3)))),
        "colors",
    ),
    ("texture-two-channels", lambda: bf.TextureColors(np.zeros((2, 2, 2)), bf.VertexUV(V[:, :2])), "texture"),
    ("texture-uint16", lambda: bf.TextureColors(np.zeros((2, 2, 3), np.uint16), bf.VertexUV(V[:, :2])), "texture"),
    ("texture-float-above-1", lambda: bf.TextureColors(np.full((2, 2, 3), 2.0), bf.VertexUV(V[:, :2])), "texture"),
    ("texture-uv-not-uvmap", lambda: bf.TextureColors(np.zeros((2, 2, 3)), V[:, :2]), "uv_map"),
    (
        "texture-interpolation",
        lambda: bf.TextureColors(np.zeros((2, 2, 3)), bf.VertexUV(V[:, :2]), interpolation="cubic"),
        "interpolation",
    ),
    (
        "texture-path-missing",
        lambda: bf.FileTextureColors("/nonexistent/tex.png", bf.VertexUV(V[:, :2])),
        "texture_path",
    ),
    ("texture-path-not-a-path", lambda: bf.FileTextureColors(42, bf.VertexUV(V[:, :2])), "texture_path"),
    ("texture-map-path-missing", lambda: bf.TextureMap("/nonexistent/rough.png"), "image_or_path"),
    ("texture-map-bad-channel", lambda: bf.TextureMap(np.zeros((2, 2)), channel=5), "channel"),
    (
        "vertex-uv-count-mismatch",
        lambda: mesh(colors=bf.TextureColors(np.zeros((2, 2, 3)), bf.VertexUV(np.zeros((3, 2))))),
        "uv_map",
    ),
    (
        "faces-uv-face-count-mismatch",
        lambda: mesh(colors=bf.TextureColors(np.zeros((2, 2, 3)), bf.FacesUV(np.zeros((3, 3, 2))))),
        "uv_map",
    ),
    (
        "faces-uv-corner-mismatch",
        lambda: mesh(faces=QUADS, colors=bf.TextureColors(np.zeros((2, 2, 3)), bf.FacesUV(np.zeros((1, 3, 2))))),
        "uv_map",
    ),
    ("faces-uv-wrong-last-dim", lambda: bf.FacesUV(np.zeros((1, 3, 3))), "uv_map"),
    ("explicit-uv-map-mismatch", lambda: mesh(uv_map=bf.VertexUV(np.zeros((5, 2)))), "uv_map"),
    # -- per-face materials ---------------------------------------------------------------------------
    (
        "faces-material-out-of-range",
        lambda: mesh(material=[M(), M()], colors=[U((1, 0, 0)), U((0, 1, 0))], faces_material=[0, 2]),
        "faces_material",
    ),
    (
        "faces-material-missing",
        lambda: mesh(material=[M(), M()], colors=[U((1, 0, 0)), U((0, 1, 0))]),
        "faces_material",
    ),
    (
        "faces-material-wrong-length",
        lambda: mesh(material=[M(), M()], colors=[U((1, 0, 0)), U((0, 1, 0))], faces_material=[0, 1, 1]),
        "faces_material",
    ),
    ("materials-colors-count-mismatch", lambda: mesh(material=[M(), M()], colors=[U((1, 0, 0))]), "colors"),
    ("material-empty-list", lambda: mesh(material=[], colors=[]), "material"),
    (
        "primitive-faces-material-missing",
        lambda: bf.Scene().renderables.add_cube_mesh(1.0, [M(), M()], [U((1, 0, 0)), U((0, 1, 0))]),
        "faces_material",
    ),
    (
        "sphere-two-materials",
        lambda: bf.Scene().renderables.add_sphere_nurbs(1.0, [M(), M()], [U((1, 0, 0)), U((0, 1, 0))]),
        "material",
    ),
    # -- rotations / poses ----------------------------------------------------------------------------
    ("rotation-mode-unknown", lambda: mesh(rotation_mode="axisangle", rotation=(1, 0, 0)), "rotation_mode"),
    ("rotation-mode-not-a-string", lambda: mesh(rotation_mode=3, rotation=(1, 0, 0)), "rotation_mode"),
    ("euler-mixed-case", lambda: mesh(rotation_mode="eulerXyZ", rotation=(1, 2, 3)), "rotation_mode"),
    ("euler-bad-axis", lambda: mesh(rotation_mode="eulerXQZ", rotation=(1, 2, 3)), "rotation_mode"),
    ("euler-angle-count", lambda: mesh(rotation_mode="eulerXY", rotation=(1, 2, 3)), "rotation"),
    ("quaternion-zero", lambda: mesh(rotation_mode="quaternionWXYZ", rotation=(0, 0, 0, 0)), "rotation"),
    ("quaternion-three-values", lambda: mesh(rotation_mode="quaternionWXYZ", rotation=(1, 0, 0)), "rotation"),
    ("quaternion-nan", lambda: mesh(rotation_mode="quaternionXYZW", rotation=(np.nan, 0, 0, 1)), "rotation"),
    ("rotmat-reflection", lambda: mesh(rotation_mode="rotmat", rotation=REFLECTION), "rotation"),
    ("rotmat-scaled", lambda: mesh(rotation_mode="rotmat", rotation=np.eye(3) * 2), "rotation"),
    ("rotmat-singular", lambda: mesh(rotation_mode="rotmat", rotation=np.zeros((3, 3))), "rotation"),
    ("rotvec-wrong-shape", lambda: mesh(rotation_mode="rotvec", rotation=(1, 0)), "rotation"),
    ("look-at-bad-target", lambda: mesh(rotation_mode="look_at", rotation=(1, 0)), "rotation"),
    ("translation-wrong-shape", lambda: mesh(translation=(1, 2)), "translation"),
    ("translation-nan", lambda: mesh(translation=(1, np.nan, 2)), "translation"),
    ("translation-setter-inf", lambda: set_attr(mesh(), "translation", (np.inf, 0, 0)), "translation"),
    ("quaternion-setter-zero", lambda: set_attr(mesh(), "quaternion", (0, 0, 0, 0)), "quaternion"),
    # -- cameras --------------------------------------------------------------------------------------
    ("fov-x-zero", lambda: persp(fov_x=0.0), "fov_x"),
    ("fov-x-pi", lambda: persp(fov_x=np.pi), "fov_x"),
    ("fov-y-negative", lambda: persp(fov_x=None, fov_y=-0.5), "fov_y"),
    ("focal-dist-zero", lambda: persp(fov_x=None, focal_dist=0.0), "focal_dist"),
    ("focal-and-fov-both", lambda: persp(focal_dist=100.0), "focal_dist"),
    ("fov-x-and-fov-y-both", lambda: persp(fov_y=1.0), "fov_y"),
    ("k-and-fov-both", lambda: persp(K=np.eye(3)), "K"),
    ("no-intrinsics", lambda: persp(fov_x=None), "focal_dist"),
    ("k-skewed", lambda: persp(fov_x=None, K=SKEWED_K), "K"),
    ("k-negative-focal", lambda: persp(fov_x=None, K=np.diag([-100.0, 100.0, 1.0])), "K"),
    ("k-wrong-shape", lambda: persp(fov_x=None, K=np.eye(2)), "K"),
    ("resolution-zero", lambda: persp(resolution=(0, 48)), "resolution"),
    ("resolution-fractional", lambda: persp(resolution=(64.5, 48)), "resolution"),
    ("resolution-three-values", lambda: persp(resolution=(64, 48, 3)), "resolution"),
    ("resolution-negative", lambda: persp(resolution=(64, -48)), "resolution"),
    ("resolution-percentage-zero", lambda: persp(resolution_percentage=0), "resolution_percentage"),
    ("near-zero", lambda: persp(near=0.0), "near"),
    ("near-equals-far", lambda: persp(near=5.0, far=5.0), "far"),
    ("near-beyond-far", lambda: persp(near=10.0, far=1.0), "far"),
    ("center-wrong-shape", lambda: persp(center=(1.0, 2.0, 3.0)), "center"),
    ("distortion-three-values", lambda: persp(distortion=(0.1, 0.0, 0.0)), "distortion"),
    ("distortion-nan", lambda: persp(distortion=(np.nan, 0.0, 0.0, 0.0)), "distortion"),
    (
        "distortion-on-orthographic",
        lambda: bf.OrthographicCamera((64, 48), distortion=(0.1, 0, 0, 0)),
        "distortion",
    ),
    ("ortho-scale-zero", lambda: bf.Scene().set_orthographic_camera((64, 48), ortho_scale=0.0), "ortho_scale"),
    (
        "opencv-reflection-r",
        lambda: bf.Scene().set_camera_from_opencv(np.diag([100.0, 100, 1]), REFLECTION, (0, 0, 0), (64, 48)),
        "R",
    ),
    (
        "opencv-t-wrong-shape",
        lambda: bf.Scene().set_camera_from_opencv(np.diag([100.0, 100, 1]), np.eye(3), (0, 0), (64, 48)),
        "t",
    ),
    ("camera-setter-wrong-type", lambda: set_attr(bf.Scene(), "camera", "camera"), "camera"),
    # -- renderables ----------------------------------------------------------------------------------
    ("point-size-negative", lambda: bf.Scene().renderables.add_pointcloud(V, M(), U((1, 1, 1)), -0.1), "point_size"),
    (
        "point-size-wrong-count",
        lambda: bf.Scene().renderables.add_pointcloud(V, M(), U((1, 1, 1)), np.full(3, 0.1)),
        "point_size",
    ),
    (
        "pointcloud-colors-count",
        lambda: bf.Scene().renderables.add_pointcloud(V, M(), bf.VertexColors(np.zeros((5, 3)))),
        "colors",
    ),
    (
        "pointcloud-base-primitive",
        lambda: bf.Scene().renderables.add_pointcloud(V, M(), U((1, 1, 1)), base_primitive="TEAPOT"),
        "base_primitive",
    ),
    ("sphere-radius-zero", lambda: bf.Scene().renderables.add_sphere_nurbs(0.0, M(), U((1, 1, 1))), "radius"),
    (
        "ellipsoid-radius-negative",
        lambda: bf.Scene().renderables.add_ellipsoid_nurbs((1, -1, 1), M(), U((1, 1, 1))),
        "radius",
    ),
    ("cube-size-negative", lambda: bf.Scene().renderables.add_cube_mesh(-1.0, M(), U((1, 1, 1))), "size"),
    ("plane-size-zero", lambda: bf.Scene().renderables.add_plane_mesh(0, M(), U((1, 1, 1))), "size"),
    (
        "cylinder-height-zero",
        lambda: bf.Scene().renderables.add_cylinder_mesh(1.0, 0.0, M(), U((1, 1, 1))),
        "height",
    ),
    (
        "circle-two-vertices",
        lambda: bf.Scene().renderables.add_circle_mesh(1.0, M(), U((1, 1, 1)), num_vertices=2),
        "num_vertices",
    ),
    (
        "circle-fill-type",
        lambda: bf.Scene().renderables.add_circle_mesh(1.0, M(), U((1, 1, 1)), fill_type="FAN"),
        "fill_type",
    ),
    (
        "curve-one-keypoint",
        lambda: bf.Scene().renderables.add_curve_nurbs([[0, 0, 0]], 0.1, M(), U((1, 1, 1))),
        "keypoints",
    ),
    (
        "curve-coincident-keypoints",
        lambda: bf.Scene().renderables.add_curve_nurbs([[1, 1, 1]] * 4, 0.1, M(), U((1, 1, 1))),
        "keypoints",
    ),
    (
        "curve-radius-negative",
        lambda: bf.Scene().renderables.add_curve_nurbs(V, -0.1, M(), U((1, 1, 1))),
        "radius",
    ),
    (
        "shadow-catcher-not-bool",
        lambda: bf.Scene().renderables.add_plane_mesh(1.0, M(), U((1, 1, 1)), shadow_catcher="yes"),
        "shadow_catcher",
    ),
    ("duplicate-renderable-tag", dup_renderable_tag, "tag"),
    ("duplicate-light-tag", dup_light_tag, "tag"),
    ("empty-tag", lambda: mesh(tag=""), "tag"),
    ("tag-not-a-string", lambda: mesh(tag=5), "tag"),
    ("update-vertices-count", lambda: mesh().update_vertices(V[:3]), "vertices"),
    ("update-vertices-nan", lambda: mesh().update_vertices(V * np.nan), "vertices"),
    ("update-colors-count", lambda: mesh().update_colors([U((1, 1, 1)), U((1, 1, 1))]), "colors"),
    ("update-colors-vertex-mismatch", lambda: mesh().update_colors(bf.VertexColors(np.zeros((9, 3)))), "colors"),
    ("update-material-count", lambda: mesh().update_material([M(), M()]), "material"),
    ("update-material-not-material", lambda: mesh().update_material("metal"), "material"),
    ("set-smooth-not-bool", lambda: mesh().set_smooth("yes"), "smooth"),
    ("emit-shadows-not-bool", lambda: set_attr(mesh(), "emit_shadows", 2), "emit_shadows"),  # 0 / 1 are booleans
    (
        "sphere-cannot-be-flat",
        lambda: bf.Scene().renderables.add_sphere_nurbs(1, M(), U((1, 1, 1))).set_smooth(False),
        "smooth",
    ),
    # -- materials ------------------------------------------------------------------------------------
    ("material-unknown-kwarg", lambda: M(clearcoat=0.5), "clearcoat"),
    ("metal-unknown-kwarg", lambda: bf.MetalMaterial(specular=0.5), "specular"),
    ("glossy-unknown-kwarg", lambda: bf.GlossyBSDFMaterial(metallic=1.0), "metallic"),
    ("material-roughness-above-1", lambda: M(roughness=1.5), "roughness"),
    ("material-ior-below-1", lambda: M(ior=0.5), "ior"),
    ("material-emission-color-wrong-length", lambda: M(emission_color=(1, 0)), "emission_color"),
    ("material-alpha-string", lambda: M(alpha="opaque"), "alpha"),
    ("material-unknown-attribute-assignment", lambda: set_material_attr("clearcoat", 0.3), "clearcoat"),
    ("material-attribute-out-of-range", lambda: set_material_attr("metallic", 2.0), "metallic"),
    ("material-attribute-nan", lambda: set_material_attr("roughness", np.nan), "roughness"),
    ("material-roughness-map-wrong-type", lambda: M(roughness_map=np.zeros((2, 2))), "roughness_map"),
    ("material-normal-map-wrong-type", lambda: M(normal_map=bf.TextureMap(np.zeros((2, 2)))), "normal_map"),
    ("glossy-distribution", lambda: bf.GlossyBSDFMaterial(distribution="PHONG"), "distribution"),
    ("material-color-space", lambda: M(color_space="aces"), "color_space"),
    # -- lights ---------------------------------------------------------------------------------------
    ("light-strength-negative", lambda: bf.Scene().lights.add_point(-1.0), "strength"),
    ("light-color-above-1", lambda: bf.Scene().lights.add_sun(color=(2, 1, 1)), "color"),
    ("light-color-int-255", lambda: bf.Scene().lights.add_point(color=(255, 255, 255)), "color"),
    ("light-use-shadow-not-bool", lambda: bf.Scene().lights.add_point(use_shadow="no"), "use_shadow"),
    ("light-strength-setter-nan", lambda: set_attr(bf.Scene().lights.add_point(), "strength", np.nan), "strength"),
    ("spot-size-zero", lambda: bf.Scene().lights.add_spot(spot_size=0.0), "spot_size"),
    ("spot-blend-above-1", lambda: bf.Scene().lights.add_spot(spot_blend=1.5), "spot_blend"),
    ("area-shape-unknown", lambda: bf.Scene().lights.add_area("triangle", 1.0), "shape"),
    ("area-square-with-pair", lambda: bf.Scene().lights.add_area("square", (1.0, 2.0)), "size"),
    ("area-rectangle-with-one-size", lambda: bf.Scene().lights.add_area("rectangle", 1.0), "size"),
    ("area-size-zero", lambda: bf.Scene().lights.add_area("circle", 0.0), "size"),
    ("area-ellipse-negative", lambda: bf.Scene().lights.add_area("ellipse", (1.0, -1.0)), "size"),
    ("sun-angular-diameter", lambda: bf.Scene().lights.add_sun(angular_diameter=4.0), "angular_diameter"),
    ("background-color-above-1", lambda: bf.Scene().lights.set_background_light(1.0, (1.5, 1, 1)), "color"),
    ("background-strength-negative", lambda: bf.Scene().lights.set_background_light(-1.0), "strength"),
    (
        "environment-path-missing",
        lambda: bf.Scene().lights.set_environment_map("/nonexistent/sky.exr"),
        "image_or_path",
    ),
    (
        "environment-negative-radiance",
        lambda: bf.Scene().lights.set_environment_map(np.full((4, 8, 3), -1.0, np.float32)),
        "image_or_path",
    ),
    # -- unknown keyword arguments --------------------------------------------------------------------
    ("add-mesh-unknown-kwarg", lambda: mesh(smoothing=True), "smoothing"),
    (
        "add-sphere-unknown-kwarg",
        lambda: bf.Scene().renderables.add_sphere_nurbs(1.0, M(), U((1, 1, 1)), segments=8),
        "segments",
    ),
    ("add-point-unknown-kwarg", lambda: bf.Scene().lights.add_point(radius=0.1), "radius"),
    ("add-area-unknown-kwarg", lambda: bf.Scene().lights.add_area("square", 1.0, power=10), "power"),
    ("set-background-unknown-kwarg", lambda: bf.Scene().lights.set_background_light(1.0, colour=(1, 1, 1)), "colour"),
    ("camera-unknown-kwarg", lambda: persp(lens=50), "lens"),
    ("ortho-camera-unknown-kwarg", lambda: bf.Scene().set_orthographic_camera((8, 8), scale=2), "scale"),
    # -- render entry point ---------------------------------------------------------------------------
    ("render-no-camera", lambda: bf.render(bf.Scene(), backend="whatever"), "camera"),
    ("render-not-a-scene", lambda: bf.render("scene.npz"), "scene"),
    ("render-unknown-backend", lambda: render(backend="povray"), "povray"),
    ("render-backend-wrong-type", lambda: render(backend=42), "backend"),
    ("render-unknown-quality", lambda: render(backend="fake", quality="ultra"), "quality"),
    ("render-unknown-output", lambda: render(backend="fake", outputs=("rgb", "flow")), "outputs"),
    ("render-empty-outputs", lambda: render(backend="fake", outputs=()), "outputs"),
    ("render-samples-zero", lambda: render(backend="fake", samples=0), "samples"),
    ("render-seed-negative", lambda: render(backend="fake", seed=-1), "seed"),
    ("render-threads-zero", lambda: render(backend="fake", threads=0), "threads"),
    ("render-unknown-backend-option", lambda: render(backend="fake", platform="egl"), "platform"),
    ("render-pixel-filter", lambda: render(backend="fake", pixel_filter="lanczos"), "pixel_filter"),
    ("render-time-limit-negative", lambda: render(backend="fake", time_limit=-1.0), "time_limit"),
    ("render-denoise-not-bool", lambda: resolve_settings(denoise="yes"), "denoise"),
    ("get-backend-unknown", lambda: bf.get_backend("povray"), "povray"),
    # -- ragged nested lists (numpy cannot even build an array) ----------------------------------------
    ("ragged-uniform-color", lambda: U([[1, 0], [0]]), "uniform_color"),
    ("ragged-vertex-colors", lambda: bf.VertexColors([[1, 0, 0], [0, 1]]), "vertex_colors"),
    ("ragged-texture", lambda: bf.TextureColors([[1, 0], [0]], bf.VertexUV(V[:, :2])), "texture"),
    ("ragged-resolution", lambda: persp(resolution=[[64, 1], [48]]), "resolution"),
    ("ragged-area-size", lambda: bf.Scene().lights.add_area("rectangle", [[1, 2], [3]]), "size"),
    (
        "ragged-point-size",
        lambda: bf.Scene().renderables.add_pointcloud(V, M(), U((1, 1, 1)), [[0.1, 0.2], [0.3]]),
        "point_size",
    ),
    ("ragged-environment", lambda: bf.Scene().lights.set_environment_map([[1.0, 2.0], [3.0]]), "image_or_path"),
    ("ragged-vertices", lambda: mesh(vertices=[[0, 0, 0], [1, 0]]), "vertices"),
    # -- results --------------------------------------------------------------------------------------
    ("result-save-missing-folder", lambda: rr().save("/nonexistent/folder/out.png"), "folder"),
    ("result-save-bad-suffix", lambda: rr().save("out.jpg"), "path"),
    ("result-save-missing-output", lambda: rr().save("out.png", output="depth"), "output"),
    ("result-save-path-none", lambda: rr().save(None), "path"),
    ("result-save-path-dict", lambda: rr().save({}), "path"),
    ("scene-save-path-none", lambda: bf.Scene().save(None), "path"),
    ("scene-load-path-int", lambda: bf.Scene.load(3), "path"),
    ("result-straight-without-rgb", lambda: RenderResult().to_srgb8(), "rgb"),
]


def test_there_are_enough_distinct_bad_inputs():
    ids = [case[0] for case in BAD_INPUTS]
    assert len(ids) == len(set(ids))
    assert len(ids) >= 40


@pytest.mark.usefixtures("fake_backend")
@pytest.mark.parametrize(("call", "words"), [c[1:] for c in BAD_INPUTS], ids=[c[0] for c in BAD_INPUTS])
def test_bad_input_raises_invalid_scene_error_naming_the_argument(call, words):
    with pytest.raises(InvalidSceneError) as info:
        call()
    err = info.value
    assert isinstance(err, ValueError) and isinstance(err, BlendifyError)
    assert words in str(err), f"message does not name {words!r}: {err}"
    assert len(str(err)) > len(words) + 10, f"message too terse: {err}"


def test_result_save_failure_leaves_no_partial_file(tmp_path):
    r = rr()
    with pytest.raises(InvalidSceneError):
        r.save(tmp_path / "out.tiff")
    with pytest.raises(InvalidSceneError):
        r.save(tmp_path / "out.png", output="normal")
    assert list(tmp_path.iterdir()) == []


def test_failed_update_keeps_the_old_state():
    m = mesh(colors=bf.VertexColors(np.zeros((4, 3))))
    old_colors, old_vertices = m.colors, m.vertices
    rev = m.revision("appearance")
    with pytest.raises(InvalidSceneError):
        m.update_colors(bf.VertexColors(np.zeros((9, 3))))
    with pytest.raises(InvalidSceneError):
        m.update_vertices(np.zeros((9, 3)))
    assert m.colors is old_colors and m.vertices is old_vertices
    assert m.revision("appearance") == rev


def test_failed_material_assignment_keeps_the_old_value():
    mat = M(roughness=0.2)
    rev = mat.revision
    with pytest.raises(InvalidSceneError):
        mat.roughness = 3.0
    assert mat.roughness == 0.2 and mat.revision == rev


def test_duplicate_tag_does_not_replace_the_first_object():
    s = bf.Scene()
    first = s.renderables.add_sphere_nurbs(1.0, M(), U((1, 1, 1)), tag="a")
    with pytest.raises(InvalidSceneError):
        s.renderables.add_cube_mesh(1.0, M(), U((1, 1, 1)), tag="a")
    assert s.renderables["a"] is first and len(s.renderables) == 1


def test_missing_tags_raise_key_error_with_the_tag():
    s = bf.Scene()
    with pytest.raises(KeyError, match="nope"):
        s.renderables["nope"]
    with pytest.raises(KeyError, match="nope"):
        s.lights.remove("nope")


# ---------------------------------------------------------------------------------------------------
# garbage fuzzing: any argument replaced by any junk value gives InvalidSceneError or works
# ---------------------------------------------------------------------------------------------------

GARBAGE = [
    None,
    "x",
    b"x",
    {},
    {"a": 1},
    [],
    [[]],
    [[1, 2], [3]],
    float("nan"),
    float("inf"),
    -1,
    0,
    1e308,
    True,
    object(),
    np.zeros((0, 3)),
    np.zeros((2, 2, 2)),
    (1, 2),
    1j,
    np.array(["a"]),
    [None, None, None],
]

_CALLS = {
    "add_mesh": (
        lambda **kw: bf.Scene().renderables.add_mesh(**kw),
        dict(vertices=V, faces=TRIS, material=M(), colors=U((1, 1, 1))),
    ),
    "add_pointcloud": (
        lambda **kw: bf.Scene().renderables.add_pointcloud(**kw),
        dict(vertices=V, material=M(), colors=U((1, 1, 1))),
    ),
    "add_cylinder_mesh": (
        lambda **kw: bf.Scene().renderables.add_cylinder_mesh(**kw),
        dict(radius=1.0, height=1.0, material=M(), colors=U((1, 1, 1))),
    ),
    "add_curve_nurbs": (
        lambda **kw: bf.Scene().renderables.add_curve_nurbs(**kw),
        dict(keypoints=V, radius=0.1, material=M(), colors=U((1, 1, 1))),
    ),
    "add_spot": (lambda **kw: bf.Scene().lights.add_spot(**kw), {}),
    "add_area": (lambda **kw: bf.Scene().lights.add_area(**kw), dict(shape="square", size=1.0)),
    "set_environment_map": (
        lambda **kw: bf.Scene().lights.set_environment_map(**kw),
        dict(image_or_path=np.ones((4, 8, 3), np.float32)),
    ),
    "set_perspective_camera": (
        lambda **kw: bf.Scene().set_perspective_camera(**kw),
        dict(resolution=(8, 8), fov_x=1.0),
    ),
    "set_camera_from_opencv": (
        lambda **kw: bf.Scene().set_camera_from_opencv(**kw),
        dict(K=np.diag([10.0, 10, 1]), R=np.eye(3), t=(0, 0, 0), resolution=(8, 8)),
    ),
    "TextureColors": (
        lambda **kw: bf.TextureColors(**kw),
        dict(texture=np.zeros((2, 2, 3)), uv_map=bf.VertexUV(np.zeros((4, 2)))),
    ),
    "PrincipledBSDFMaterial": (
        lambda **kw: bf.PrincipledBSDFMaterial(**kw),
        dict(roughness=0.5, emission_color=(1, 1, 1)),
    ),
    "resolve_settings": (lambda **kw: resolve_settings(**kw), dict(quality="draft", samples=4, outputs=("rgb",))),
}


def _fuzz_cases():
    import inspect

    for label, (fn, base) in _CALLS.items():
        target = {
            "add_mesh": bf.ir.renderables.RenderablesCollection.add_mesh,
            "add_pointcloud": bf.ir.renderables.RenderablesCollection.add_pointcloud,
            "add_cylinder_mesh": bf.ir.renderables.RenderablesCollection.add_cylinder_mesh,
            "add_curve_nurbs": bf.ir.renderables.RenderablesCollection.add_curve_nurbs,
            "add_spot": bf.ir.lights.LightsCollection.add_spot,
            "add_area": bf.ir.lights.LightsCollection.add_area,
            "set_environment_map": bf.ir.lights.LightsCollection.set_environment_map,
            "set_perspective_camera": bf.Scene.set_perspective_camera,
            "set_camera_from_opencv": bf.Scene.set_camera_from_opencv,
            "TextureColors": bf.TextureColors.__init__,
            "PrincipledBSDFMaterial": bf.PrincipledBSDFMaterial.__init__,
            "resolve_settings": resolve_settings,
        }[label]
        names = [n for n in inspect.signature(target).parameters if n not in ("self", "kwargs")]
        for name in names:
            yield pytest.param(fn, base, name, id=f"{label}-{name}")


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
@pytest.mark.parametrize(("fn", "base", "name"), list(_fuzz_cases()))
def test_garbage_in_any_argument_is_a_clear_error_or_accepted(fn, base, name):
    for junk in GARBAGE:
        kwargs = dict(base)
        kwargs[name] = junk
        try:
            fn(**kwargs)
        except InvalidSceneError as exc:
            assert str(exc), "empty message"
        except Exception as exc:  # noqa: BLE001 - the point of the test
            pytest.fail(f"{name}={junk!r:.40} raised {type(exc).__name__}: {exc}")


RENDER_ARGUMENTS = [
    "quality",
    "samples",
    "seed",
    "outputs",
    "threads",
    "strict",
    "denoise",
    "max_bounces",
    "time_limit",
    "target_error",
    "pixel_filter",
    "clamp_direct",
    "clamp_indirect",
    "adaptive",
    "transparent_background",
    "effects",
    "pattern",  # a backend option of the fake
]


@pytest.mark.usefixtures("fake_backend")
@pytest.mark.filterwarnings("ignore::UserWarning")
@pytest.mark.parametrize("name", RENDER_ARGUMENTS)
def test_garbage_render_arguments_are_clear_errors(name):
    scene = scene_with_camera()
    for junk in GARBAGE + [2.5]:
        try:
            bf.render(scene, backend="fake", **{name: junk})
        except BlendifyError as exc:
            assert str(exc)
        except Exception as exc:  # noqa: BLE001 - the point of the test
            pytest.fail(f"render({name}={junk!r:.40}) raised {type(exc).__name__}: {exc}")
