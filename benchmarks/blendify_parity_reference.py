"""blendify 2.1's own renders of the parity scenes (``blendify_parity_scenes.py``): run ONCE, in a separate
environment with blendify 2.1 and its Blender (it imports bpy 4.5 and blendify's singleton scene):

    uv venv /tmp/bf21 --python 3.11
    uv pip install --python /tmp/bf21 blendify==2.1.0 bpy==4.5.2
    /tmp/bf21/bin/python benchmarks/blendify_parity_reference.py benchmarks/results/blendify_parity

It writes ``ref_<scene>.png`` (blendify's PNG, RGBA 8-bit, as ``scene.render(filepath=...)`` writes it) and
``reference.json`` (versions, times). The PNGs are committed; ``blendify_parity.py`` compares with them.
Nothing here is blendify's code: only calls of its public API, written for these scenes.
"""

from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import blendify_parity_scenes as P  # noqa: E402


def _materials():  # imported late: blendify imports bpy
    from blendify import materials as M

    return M


def build(name: str) -> None:
    from blendify import scene
    from blendify.colors import TextureColors, UniformColors, VertexColors, VertexUV

    M = _materials()
    w, h = P.RESOLUTION
    r, lights = scene.renderables, scene.lights
    if name == "readme_cube":
        scene.set_perspective_camera((w, h), fov_x=0.7, rotation=(0.82, 0.42, 0.18, 0.34), translation=(5, -5, 5))
        lights.add_point(strength=1000, translation=(4, -2, 4))
        r.add_cube_mesh(1.0, M.PrincipledBSDFMaterial(), UniformColors((0.0, 1.0, 0.0)))
    elif name == "nurbs_primitives":
        scene.set_perspective_camera((w, h), focal_dist=640 * w / 1280)
        lights.add_sun(strength=5.0)
        r.add_sphere_nurbs(1.0, M.PrincipledBSDFMaterial(), UniformColors((0.3, 0.0, 0.9)), translation=(0, 0, -4.5))
        r.add_circle_mesh(0.7, M.PrincipledBSDFMaterial(), UniformColors((0.5, 0.3, 0.9)), translation=(0, 1, -4.5))
        r.add_cylinder_mesh(
            1.3, 2.3, M.PrincipledBSDFMaterial(), UniformColors((0.0, 0.9, 0.9)), translation=(1, 1, -8)
        )
        keys = np.array([[1, 0, 0.0], [-1, 0, 0], [0, -2, -4], [-1, -3, -6]])
        r.add_curve_nurbs(keys, 0.1, M.PrincipledBSDFMaterial(), UniformColors((1.0, 0.0, 0.2)))
    elif name == "materials_catcher":
        v, f = P.bumpy_blob()
        mats = [M.PlasticMaterial(), M.MetalMaterial(), M.PlasticWireframeMaterial(wireframe_thickness=0.01)]
        cols = [(0.8, 0.3, 0.2), (0.7, 0.7, 0.75), (0.2, 0.6, 0.3)]
        for x, mat, col in zip((-1.2, 0.0, 1.2), mats, cols):
            m = r.add_mesh(v, f, mat, UniformColors(col), translation=(x, 0.0, 0.65))
            m.set_smooth(True)
        r.add_plane_mesh(25.0, M.PrincipledBSDFMaterial(), UniformColors((1.0, 1.0, 1.0)), shadow_catcher=True)
        scene.set_perspective_camera(
            (w, h), fov_x=np.deg2rad(40), rotation_mode="look_at", rotation=(0, 0, 0.5), translation=(0, -5, 2.2)
        )
        lights.set_background_light(0.03)
        lights.add_point(strength=600, use_shadow=False, translation=(2, -3, 4))
        lights.add_spot(
            strength=250, spot_size=0.83, spot_blend=0.458, rotation_mode="look_at", rotation=(0, 0, 0.5),
            translation=(-3, -3, 4),
        )  # fmt: skip
    elif name == "cornell_primitives":
        walls = M.PrincipledBSDFMaterial(roughness=0.8)
        white, red, green = (0.8, 0.8, 0.8), (0.8, 0.1, 0.1), (0.1, 0.8, 0.1)
        e = "eulerXYZ"
        r.add_plane_mesh(2.0, walls, UniformColors(white), translation=(0, 0, 0))
        r.add_plane_mesh(2.0, walls, UniformColors(white), rotation_mode=e, rotation=(180, 0, 0), translation=(0, 0, 2))
        r.add_plane_mesh(2.0, walls, UniformColors(white), rotation_mode=e, rotation=(90, 0, 0), translation=(0, 1, 1))
        r.add_plane_mesh(2.0, walls, UniformColors(red), rotation_mode=e, rotation=(0, 90, 0), translation=(-1, 0, 1))
        r.add_plane_mesh(2.0, walls, UniformColors(green), rotation_mode=e, rotation=(0, -90, 0), translation=(1, 0, 1))
        lights.add_area("square", 0.5, strength=40, translation=(0, 0, 1.98))
        glass = M.PrincipledBSDFMaterial(transmission_weight=1.0, roughness=0.05, ior=1.45)
        r.add_sphere_nurbs(0.35, glass, UniformColors((1.0, 1.0, 1.0)), translation=(-0.4, -0.2, 0.35))
        r.add_sphere_nurbs(0.3, M.MetalMaterial(), UniformColors((0.9, 0.6, 0.3)), translation=(0.45, 0.3, 0.3))
        r.add_cylinder_mesh(
            0.15,
            0.6,
            M.GlossyBSDFMaterial(roughness=0.2),
            UniformColors((0.9, 0.8, 0.3)),
            translation=(0.5, -0.45, 0.3),
        )
        r.add_circle_mesh(
            0.25, M.MetalMaterial(), UniformColors((0.8, 0.8, 0.9)), rotation_mode=e, rotation=(70, 0, 20),
            translation=(-0.5, 0.6, 1.0),
        )  # fmt: skip
        scene.set_perspective_camera(
            (w, h), fov_x=np.deg2rad(39.1), rotation_mode=e, rotation=(90, 0, 0), translation=(0, -3.2, 1.0)
        )
    elif name == "textured_sheet":
        v, f, uv = P.quad_grid()
        r.add_mesh(v, f, M.PrincipledBSDFMaterial(roughness=0.6), TextureColors(P.checker(), VertexUV(uv)))
        scene.set_perspective_camera(
            (w, h), fov_x=np.deg2rad(45), rotation_mode="look_at", rotation=(0, 0, 0), translation=(0, -3.2, 1.6)
        )
        lights.add_sun(strength=3.0, rotation_mode="eulerXYZ", rotation=(30, 20, 0))
        lights.set_background_light(0.2)
    elif name == "pointcloud":
        pts, cols = P.spiral_points()
        r.add_pointcloud(pts, M.PrincipledBSDFMaterial(), VertexColors(cols), point_size=0.01, base_primitive="SPHERE")
        scene.set_perspective_camera(
            (w, h), fov_x=np.deg2rad(50), rotation_mode="look_at", rotation=(0, 0, -0.1), translation=(0, -3.5, 1.2)
        )
        lights.add_point(strength=300, translation=(2, -2, 2))
        lights.add_point(strength=300, translation=(-2, -1, 3))
    elif name == "ex01_cornell_box":  # examples/01_cornell_box.py at a smaller size
        path, _, res = P.ASSET_SCENES[name]
        scene.attach_blend(str(P.asset_path(path)))
        scene.set_perspective_camera(
            res, fov_x=np.deg2rad(39.1), rotation=(-0.707, -0.707, 0.0, 0.0), translation=[-0.278, -0.800, 0.273]
        )
        lights.add_area(
            shape="square", size=5, strength=40, use_shadow=False, rotation=(-0.707, -0.707, 0.0, 0.0),
            translation=[-0.278, -1, 0.273],
        )  # fmt: skip
        m1 = M.PrincipledBSDFMaterial(
            specular_ior=0.5, sheen_weight=0.0, sheen_roughness=0.4, ior=1.46, transmission_weight=1.0, alpha=0.7,
            coat_ior=1.0, coat_roughness=0.0,
        )  # fmt: skip
        r.add_sphere_nurbs(0.08, m1, UniformColors((1.0, 153 / 255, 102 / 255)), translation=[-0.22, 0.05, 0.08])
        m2 = M.PrincipledBSDFMaterial(
            metallic=1.0, specular_ior=0.5, roughness=0.07, sheen_roughness=0.4, coat_ior=0.2, coat_roughness=0.4
        )
        r.add_sphere_nurbs(0.08, m2, UniformColors((1.0, 1.0, 1.0)), translation=[-0.12, 0.25, 0.08])
        r.add_cylinder_mesh(
            0.08, 0.3, M.GlossyBSDFMaterial(roughness=0.5), UniformColors((102 / 255, 102 / 255, 1.0)),
            translation=[-0.32, 0.25, 0.15],
        )  # fmt: skip
        m3 = M.PrincipledBSDFMaterial(
            metallic=1.0, specular_ior=0.5, roughness=0.05, sheen_roughness=0.8, coat_ior=0.8, coat_roughness=0.1
        )
        r.add_circle_mesh(
            0.17, m3, UniformColors((1.0, 1.0, 1.0)), rotation=[0.720, 0.262, 0.604, -0.220],
            translation=[-0.43, 0.32, 0.18],
        )  # fmt: skip
    elif name == "ex07_materials":  # examples/07_materials_and_shadow_catcher.py at a smaller size
        import trimesh

        path, _, res = P.ASSET_SCENES[name]
        mesh = trimesh.load(str(P.asset_path(path)), process=False)
        v, f = np.array(mesh.vertices), np.array(mesh.faces)
        plastic = r.add_mesh(v, f, material=M.PlasticMaterial(), colors=UniformColors((0.64, 0.8, 0.96)))
        plastic.set_smooth(True)
        plastic.translation = plastic.translation + np.array([2.0, 0, 0])
        metal = r.add_mesh(v, f, material=M.MetalMaterial(), colors=UniformColors((0.94, 0.62, 0.46)))
        metal.set_smooth(True)
        wire = r.add_mesh(
            v,
            f,
            material=M.PlasticWireframeMaterial(wireframe_thickness=0.0035),
            colors=UniformColors((0.2, 1.0, 0.47)),
        )
        wire.set_smooth(True)
        wire.translation = wire.translation + np.array([-2.0, 0, 0])
        plane = r.add_plane_mesh(
            25.0, shadow_catcher=True, material=M.PrincipledBSDFMaterial(), colors=UniformColors((0.5, 0.5, 0.5))
        )
        plane.translation = np.array([0, -4, v[:, 2].min() - 0.01])
        scene.set_perspective_camera(
            res, fov_x=np.deg2rad(30), translation=(0.6, 13.5, 4.5), rotation_mode="look_at", rotation=metal
        )
        lights.set_background_light(0.03)
        lights.add_point(strength=600, shadow_soft_size=1.0, translation=(4, 6, 5), use_shadow=False)
        lights.add_spot(
            strength=250, spot_size=np.deg2rad(47.6), spot_blend=0.458, translation=(-1.5, 4.15, 5),
            rotation=(0.930, -0.321, -0.152, -0.093),
        )  # fmt: skip
    else:
        raise SystemExit(f"unknown scene {name!r}")


def main(out_dir: str) -> int:
    from importlib import metadata

    from blendify import scene

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    info: dict[str, object] = {
        "blendify": metadata.version("blendify"),
        "bpy": metadata.version("bpy"),
        "resolution": list(P.RESOLUTION),
        "samples": P.SAMPLES,
        "call": "scene.render(filepath, use_gpu=False, samples=SAMPLES) (aa_filter_width 1.5; use_denoiser only for "
        "ex01, as blendify's example 01)",
        "seconds": {},
    }
    names = [n for n in sys.argv[2:]] or list(P.SCENES) + list(P.ASSET_SCENES)
    for name in names:
        if name in P.ASSET_SCENES and P.asset_path(P.ASSET_SCENES[name][0]) is None:
            print(f"{name}: skipped, {P.ASSET_SCENES[name][0]} is not in $BLENDIFY_THIRD_PARTY_DIR", flush=True)
            continue
        scene.clear()
        build(name)
        t0 = time.perf_counter()
        # example 01 renders denoised, as blendify's example does
        denoise = name == "ex01_cornell_box"
        scene.render(filepath=str(out / f"ref_{name}.png"), use_gpu=False, samples=P.SAMPLES, use_denoiser=denoise)
        info["seconds"][name] = round(time.perf_counter() - t0, 2)  # type: ignore[index]
        print(name, info["seconds"][name], "s", flush=True)  # type: ignore[index]
    old = json.loads((out / "reference.json").read_text()) if (out / "reference.json").is_file() else {}
    info["seconds"] = {**old.get("seconds", {}), **info["seconds"]}  # type: ignore[dict-item]
    (out / "reference.json").write_text(json.dumps(info, indent=2) + "\n")
    sys.stdout.flush()
    os._exit(0)  # blendify's own atexit hook exits with 0 anyway; the files are written


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1] if len(sys.argv) > 1 else "benchmarks/results/blendify_parity"))
