"""blendify 2.1 parity: the scenes of ``blendify_parity_scenes.py`` ported to blendify-core by following the
README's migration table alone, rendered with ``quality="blendify"`` (Cycles), compared with blendify 2.1's
own renders of the same scenes (``results/blendify_parity/ref_*.png``, made once by
``blendify_parity_reference.py`` in a separate blendify 2.1 + bpy 4.5.2 environment).

    python benchmarks/blendify_parity.py            # writes results/blendify_parity.md and .png

What the port changes, each a row of the migration table: ``UniformColors(..., color_space="linear")``
(blendify's uniform colours were scene-linear); a point cloud's ``point_size`` is the sphere diameter (5x
blendify's value for its spheres) and ``particle_emission_strength=1`` is passed (blendify's default);
``m.set_smooth(True)`` and the primitives' smooth shading are unchanged. Nothing else is edited.

Metrics on the images composited over white (sRGB, 8-bit): SSIM (scikit-image), mean absolute difference
in 8-bit levels, and the share of pixels whose alpha differs by more than half. Goal: SSIM >= 0.97.
"""

from __future__ import annotations

import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import blendify_parity_scenes as P  # noqa: E402

import blendify_core as bf  # noqa: E402

RESULTS = HERE / "results"
REFS = RESULTS / "blendify_parity"
GOAL = 0.97


def _lin(rgb: tuple[float, float, float]) -> bf.UniformColors:
    return bf.UniformColors(rgb, color_space="linear")


def build(name: str) -> bf.Scene:
    """The blendify-core port of scene ``name`` (see blendify_parity_reference.build for the original)."""
    s = bf.Scene()
    w, h = P.RESOLUTION
    r, lights = s.renderables, s.lights
    if name == "readme_cube":
        s.set_perspective_camera((w, h), fov_x=0.7, rotation=(0.82, 0.42, 0.18, 0.34), translation=(5, -5, 5))
        lights.add_point(strength=1000, translation=(4, -2, 4))
        r.add_cube_mesh(1.0, bf.PrincipledBSDFMaterial(), _lin((0.0, 1.0, 0.0)))
    elif name == "nurbs_primitives":
        s.set_perspective_camera((w, h), focal_dist=640 * w / 1280)
        lights.add_sun(strength=5.0)
        r.add_sphere_nurbs(1.0, bf.PrincipledBSDFMaterial(), _lin((0.3, 0.0, 0.9)), translation=(0, 0, -4.5))
        r.add_circle_mesh(0.7, bf.PrincipledBSDFMaterial(), _lin((0.5, 0.3, 0.9)), translation=(0, 1, -4.5))
        r.add_cylinder_mesh(1.3, 2.3, bf.PrincipledBSDFMaterial(), _lin((0.0, 0.9, 0.9)), translation=(1, 1, -8))
        keys = np.array([[1, 0, 0.0], [-1, 0, 0], [0, -2, -4], [-1, -3, -6]])
        r.add_curve_nurbs(keys, 0.1, bf.PrincipledBSDFMaterial(), _lin((1.0, 0.0, 0.2)))
    elif name == "materials_catcher":
        v, f = P.bumpy_blob()
        mats = [bf.PlasticMaterial(), bf.MetalMaterial(), bf.PlasticWireframeMaterial(wireframe_thickness=0.01)]
        cols = [(0.8, 0.3, 0.2), (0.7, 0.7, 0.75), (0.2, 0.6, 0.3)]
        for x, mat, col in zip((-1.2, 0.0, 1.2), mats, cols):
            m = r.add_mesh(v, f, mat, _lin(col), translation=(x, 0.0, 0.65))
            m.set_smooth(True)
        r.add_plane_mesh(25.0, bf.PrincipledBSDFMaterial(), _lin((1.0, 1.0, 1.0)), shadow_catcher=True)
        s.set_perspective_camera(
            (w, h), fov_x=np.deg2rad(40), rotation_mode="look_at", rotation=(0, 0, 0.5), translation=(0, -5, 2.2)
        )
        lights.set_background_light(0.03)
        lights.add_point(strength=600, use_shadow=False, translation=(2, -3, 4))
        lights.add_spot(
            strength=250, spot_size=0.83, spot_blend=0.458, rotation_mode="look_at", rotation=(0, 0, 0.5),
            translation=(-3, -3, 4),
        )  # fmt: skip
    elif name == "cornell_primitives":
        walls = bf.PrincipledBSDFMaterial(roughness=0.8)
        white, red, green = (0.8, 0.8, 0.8), (0.8, 0.1, 0.1), (0.1, 0.8, 0.1)
        e = "eulerXYZ"
        r.add_plane_mesh(2.0, walls, _lin(white), translation=(0, 0, 0))
        r.add_plane_mesh(2.0, walls, _lin(white), rotation_mode=e, rotation=(180, 0, 0), translation=(0, 0, 2))
        r.add_plane_mesh(2.0, walls, _lin(white), rotation_mode=e, rotation=(90, 0, 0), translation=(0, 1, 1))
        r.add_plane_mesh(2.0, walls, _lin(red), rotation_mode=e, rotation=(0, 90, 0), translation=(-1, 0, 1))
        r.add_plane_mesh(2.0, walls, _lin(green), rotation_mode=e, rotation=(0, -90, 0), translation=(1, 0, 1))
        lights.add_area("square", 0.5, strength=40, translation=(0, 0, 1.98))
        glass = bf.PrincipledBSDFMaterial(transmission_weight=1.0, roughness=0.05, ior=1.45)
        r.add_sphere_nurbs(0.35, glass, _lin((1.0, 1.0, 1.0)), translation=(-0.4, -0.2, 0.35))
        r.add_sphere_nurbs(0.3, bf.MetalMaterial(), _lin((0.9, 0.6, 0.3)), translation=(0.45, 0.3, 0.3))
        r.add_cylinder_mesh(
            0.15, 0.6, bf.GlossyBSDFMaterial(roughness=0.2), _lin((0.9, 0.8, 0.3)), translation=(0.5, -0.45, 0.3)
        )
        r.add_circle_mesh(
            0.25, bf.MetalMaterial(), _lin((0.8, 0.8, 0.9)), rotation_mode=e, rotation=(70, 0, 20),
            translation=(-0.5, 0.6, 1.0),
        )  # fmt: skip
        s.set_perspective_camera(
            (w, h), fov_x=np.deg2rad(39.1), rotation_mode=e, rotation=(90, 0, 0), translation=(0, -3.2, 1.0)
        )
    elif name == "textured_sheet":
        v, f, uv = P.quad_grid()
        r.add_mesh(v, f, bf.PrincipledBSDFMaterial(roughness=0.6), bf.TextureColors(P.checker(), bf.VertexUV(uv)))
        s.set_perspective_camera(
            (w, h), fov_x=np.deg2rad(45), rotation_mode="look_at", rotation=(0, 0, 0), translation=(0, -3.2, 1.6)
        )
        lights.add_sun(strength=3.0, rotation_mode="eulerXYZ", rotation=(30, 20, 0))
        lights.set_background_light(0.2)
    elif name == "pointcloud":
        pts, cols = P.spiral_points()
        # blendify's spheres render with diameter 5 x point_size and glow with strength 1 by default
        r.add_pointcloud(
            pts, bf.PrincipledBSDFMaterial(), bf.VertexColors(cols), point_size=5 * 0.01, particle_emission_strength=1
        )
        s.set_perspective_camera(
            (w, h), fov_x=np.deg2rad(50), rotation_mode="look_at", rotation=(0, 0, -0.1), translation=(0, -3.5, 1.2)
        )
        lights.add_point(strength=300, translation=(2, -2, 2))
        lights.add_point(strength=300, translation=(-2, -1, 3))
    elif name == "ex01_cornell_box":  # examples/01_cornell_box.py, ported by the migration table
        path, _, res = P.ASSET_SCENES[name]
        s.attach_blend(str(P.asset_path(path)))
        s.set_perspective_camera(
            res, fov_x=np.deg2rad(39.1), rotation=(-0.707, -0.707, 0.0, 0.0), translation=[-0.278, -0.800, 0.273]
        )
        lights.add_area(
            shape="square", size=5, strength=40, use_shadow=False, rotation=(-0.707, -0.707, 0.0, 0.0),
            translation=[-0.278, -1, 0.273],
        )  # fmt: skip
        m1 = bf.PrincipledBSDFMaterial(
            specular_ior=0.5, sheen_weight=0.0, sheen_roughness=0.4, ior=1.46, transmission_weight=1.0, alpha=0.7,
            coat_ior=1.0, coat_roughness=0.0,
        )  # fmt: skip
        r.add_sphere_nurbs(0.08, m1, _lin((1.0, 153 / 255, 102 / 255)), translation=[-0.22, 0.05, 0.08])
        m2 = bf.PrincipledBSDFMaterial(
            metallic=1.0, specular_ior=0.5, roughness=0.07, sheen_roughness=0.4, coat_ior=0.2, coat_roughness=0.4
        )
        r.add_sphere_nurbs(0.08, m2, _lin((1.0, 1.0, 1.0)), translation=[-0.12, 0.25, 0.08])
        r.add_cylinder_mesh(
            0.08, 0.3, bf.GlossyBSDFMaterial(roughness=0.5), _lin((102 / 255, 102 / 255, 1.0)),
            translation=[-0.32, 0.25, 0.15],
        )  # fmt: skip
        m3 = bf.PrincipledBSDFMaterial(
            metallic=1.0, specular_ior=0.5, roughness=0.05, sheen_roughness=0.8, coat_ior=0.8, coat_roughness=0.1
        )
        r.add_circle_mesh(
            0.17, m3, _lin((1.0, 1.0, 1.0)), rotation=[0.720, 0.262, 0.604, -0.220], translation=[-0.43, 0.32, 0.18]
        )
    elif name == "ex07_materials":  # examples/07_materials_and_shadow_catcher.py, ported by the migration table
        import trimesh

        path, _, res = P.ASSET_SCENES[name]
        mesh = trimesh.load(str(P.asset_path(path)), process=False)
        v, f = np.array(mesh.vertices), np.array(mesh.faces)
        plastic = r.add_mesh(v, f, material=bf.PlasticMaterial(), colors=_lin((0.64, 0.8, 0.96)))
        plastic.set_smooth(True)
        plastic.translation = plastic.translation + np.array([2.0, 0, 0])
        metal = r.add_mesh(v, f, material=bf.MetalMaterial(), colors=_lin((0.94, 0.62, 0.46)))
        metal.set_smooth(True)
        wire = r.add_mesh(
            v, f, material=bf.PlasticWireframeMaterial(wireframe_thickness=0.0035), colors=_lin((0.2, 1.0, 0.47))
        )
        wire.set_smooth(True)
        wire.translation = wire.translation + np.array([-2.0, 0, 0])
        plane = r.add_plane_mesh(
            25.0, shadow_catcher=True, material=bf.PrincipledBSDFMaterial(), colors=_lin((0.5, 0.5, 0.5))
        )
        plane.translation = np.array([0, -4, v[:, 2].min() - 0.01])
        s.set_perspective_camera(
            res, fov_x=np.deg2rad(30), translation=(0.6, 13.5, 4.5), rotation_mode="look_at", rotation=metal
        )
        lights.set_background_light(0.03)
        lights.add_point(strength=600, shadow_soft_size=1.0, translation=(4, 6, 5), use_shadow=False)
        lights.add_spot(
            strength=250, spot_size=np.deg2rad(47.6), spot_blend=0.458, translation=(-1.5, 4.15, 5),
            rotation=(0.930, -0.321, -0.152, -0.093),
        )  # fmt: skip
    else:
        raise KeyError(name)
    return s


def _over_white(rgba8: np.ndarray) -> np.ndarray:
    """(H, W, 3) float sRGB in [0, 1] of straight-alpha sRGB bytes composited over white (in display space,
    as an image viewer shows a PNG)."""
    x = rgba8.astype(np.float64) / 255.0
    return x[..., :3] * x[..., 3:4] + (1.0 - x[..., 3:4])


def _blur(x: np.ndarray, sigma: float = 1.0) -> np.ndarray:
    from scipy.ndimage import gaussian_filter

    return np.stack([gaussian_filter(x[..., c], sigma) for c in range(x.shape[-1])], axis=-1)


def compare(ref8: np.ndarray, ours8: np.ndarray) -> dict[str, float]:
    from skimage.metrics import structural_similarity

    a, b = _over_white(ref8), _over_white(ours8)
    return {
        "ssim": float(structural_similarity(a, b, channel_axis=-1, data_range=1.0)),
        # Monte-Carlo noise of two independent 128 spp renders lowers SSIM by itself: after a 1 px Gaussian
        # blur the noise is mostly gone and what remains is the picture
        "ssim_blur1": float(structural_similarity(_blur(a), _blur(b), channel_axis=-1, data_range=1.0)),
        "mean_abs_levels": float(np.abs(a - b).mean() * 255.0),
        "alpha_mismatch": float((np.abs(ref8[..., 3].astype(int) - ours8[..., 3].astype(int)) > 127).mean()),
    }


def main() -> int:
    import warnings

    from PIL import Image

    from blendify_core.utils.image import contact_sheet

    ref_info_path = REFS / "reference.json"
    if not ref_info_path.is_file():
        print(f"no reference renders in {REFS}: run blendify_parity_reference.py in a blendify 2.1 environment first")
        return 1
    ref_info = json.loads(ref_info_path.read_text())
    rows, tiles, labels, skipped = [], [], [], []
    scenes = dict(P.SCENES)
    for name, (asset, what, _res) in P.ASSET_SCENES.items():
        if P.asset_path(asset) is None or not (REFS / f"ref_{name}.png").is_file():
            skipped.append(f"{name}: {asset} is not in $BLENDIFY_THIRD_PARTY_DIR (or its reference is missing)")
            continue
        scenes[name] = what
    for name, what in scenes.items():
        ref = np.asarray(Image.open(REFS / f"ref_{name}.png").convert("RGBA"))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", bf.BlenderClampWarning)  # blendify's coat_ior < 1, on purpose
            scene = build(name)
        # example 01 renders denoised, as blendify's example does (use_denoiser=True -> denoise=True)
        denoise = name == "ex01_cornell_box"
        t0 = time.perf_counter()
        result = bf.render(scene, "cycles", quality="blendify", samples=P.SAMPLES, seed=0, denoise=denoise)
        seconds = time.perf_counter() - t0
        ours = result.to_srgb8()
        m = compare(ref, ours)
        # the noise ceiling: the same port rendered again with another seed
        again = bf.render(scene, "cycles", quality="blendify", samples=P.SAMPLES, seed=1, denoise=denoise).to_srgb8()
        m["ssim_seed"] = compare(ours, again)["ssim"]
        rows.append((name, what, m, seconds, ref_info["seconds"].get(name)))
        diff = np.abs(_over_white(ref) - _over_white(ours)).mean(axis=-1)
        heat = np.clip(diff * 8.0, 0, 1)  # x8: 1/8 (32 levels) is white
        tiles += [ref, ours, np.repeat(heat[..., None], 3, axis=2).astype(np.float32)]
        labels += [f"{name}: blendify 2.1", f"blendify-core (SSIM {m['ssim']:.3f})", "|diff| x8"]
        print(
            f"{name:20s} SSIM {m['ssim']:.4f} (blurred {m['ssim_blur1']:.4f}; seed vs seed {m['ssim_seed']:.4f})  "
            f"mean |diff| {m['mean_abs_levels']:.2f} levels  {seconds:.1f} s"
        )
    sheet = contact_sheet(tiles, labels, ncols=3, linear=False)
    # a 256-colour palette keeps the committed sheet small (560 -> 167 KiB); the SSIMs come from the renders
    palette = Image.fromarray(sheet).quantize(colors=256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
    palette.save(RESULTS / "blendify_parity.png", optimize=True)
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    lines = [
        "# blendify 2.1 parity",
        "",
        "Scenes of `benchmarks/blendify_parity_scenes.py`, built through blendify 2.1's API "
        f"(blendify {ref_info['blendify']}, bpy {ref_info['bpy']}, `{ref_info['call']}`) and ported to "
        "blendify-core following the README's migration table, rendered with Cycles "
        f'(bpy {bf.get_backend_class("cycles").engine_version()}) and `quality="blendify"`, '
        f"{P.RESOLUTION[0]}x{P.RESOLUTION[1]} (ex01 160x160, ex07 240x135), {P.SAMPLES} spp. Metrics over "
        f"white, sRGB 8-bit; goal SSIM >= {GOAL}. The `ex*` rows are blendify 2.1's own examples on its assets, read "
        "from $BLENDIFY_THIRD_PARTY_DIR (not committed: tests/third_party/SOURCES.md); ex01 is denoised in both, as "
        "blendify's example renders it.",
        "",
        "SSIM (blurred): both images blurred by a 1 px Gaussian first (removes most Monte-Carlo noise). Noise "
        "ceiling: SSIM of the blendify-core port against itself rendered with another seed; an SSIM near it "
        "means the remaining difference is noise, not the picture.",
        "",
        "| scene | what it stands for | SSIM | SSIM (blurred) | noise ceiling | mean abs diff (levels) | "
        "alpha mismatch | blendify-core s | blendify 2.1 s |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for name, what, m, sec, ref_sec in rows:
        ok = "" if m["ssim"] >= GOAL else " (below goal)"
        lines.append(
            f"| {name} | {what} | {m['ssim']:.4f}{ok} | {m['ssim_blur1']:.4f} | {m['ssim_seed']:.4f} | "
            f"{m['mean_abs_levels']:.2f} | {m['alpha_mismatch']:.4f} | {sec:.1f} | "
            f"{ref_sec if ref_sec is not None else '-'} |"
        )
    if skipped:
        lines += ["", "Skipped: " + "; ".join(skipped) + "."]
    lines += [
        "",
        f"Times on a shared 2-core machine (load average {load:.1f} at the end of this run; the reference times "
        "were taken in another run): compare within a row with care.",
        f"Machine: {platform.platform()}, Python {platform.python_version()}. Contact sheet: "
        "[blendify_parity.png](blendify_parity.png) (blendify 2.1 | blendify-core | |difference| x 8).",
        "",
    ]
    (RESULTS / "blendify_parity.md").write_text("\n".join(lines))
    print(f"wrote {RESULTS / 'blendify_parity.md'} and {RESULTS / 'blendify_parity.png'}")
    return 0 if all(m["ssim"] >= GOAL for _, _, m, _, _ in rows) else 1


if __name__ == "__main__":
    raise SystemExit(main())
