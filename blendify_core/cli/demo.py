"""The built-in demo: a procedural donut shown the way the blendify paper's Figure 1 shows a mesh —
colour render, depth map, albedo, rich materials, a point cloud and advanced lighting — rendered with the
best available backend into one labelled contact sheet."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from blendify_core.errors import RenderError
from blendify_core.io.output import atomic_write
from blendify_core.ir.colors import UniformColors, VertexColors
from blendify_core.ir.colorspace import linear_to_srgb8
from blendify_core.ir.geometry import torus
from blendify_core.ir.materials import (
    DiffuseMaterial,
    MetalMaterial,
    PlasticMaterial,
    PlasticWireframeMaterial,
    PrincipledBSDFMaterial,
)
from blendify_core.ir.scene import Scene
from blendify_core.pipeline.render import render
from blendify_core.pipeline.result import RenderResult, depth_to_image
from blendify_core.typing import UInt8Array

__all__ = ["donut_scene", "run_demo"]

DOUGH = (0.80, 0.55, 0.30)
ICING = (0.93, 0.45, 0.62)


def _donut_mesh() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = torus(0.5, 0.22, 96, 48)
    v = t.vertices.copy()
    # icing on the top half, with a wavy border
    angle = np.arctan2(v[:, 1], v[:, 0])
    border = 0.02 + 0.025 * np.sin(7 * angle)
    icing = v[:, 2] > border
    colors = np.where(icing[:, None], ICING, DOUGH)
    return v, t.faces, colors


def donut_scene(panel: str = "color", resolution: tuple[int, int] = (256, 256)) -> Scene:
    """The demo scene for one panel: "color" (vertex-coloured donut on a plate), "materials" (metal,
    plastic and wireframe donuts), "pointcloud" (the donut as coloured points), "lighting" (spot + area
    lights and a shadow catcher)."""
    scene = Scene()
    v, f, c = _donut_mesh()
    r = scene.renderables
    cam_pos, target = (0.0, -2.1, 1.55), (0.0, 0.0, -0.05)
    if panel == "color":
        r.add_mesh(v, f, PrincipledBSDFMaterial(roughness=0.5), VertexColors(c), smooth=True, tag="donut")
        r.add_cylinder_mesh(
            0.85,
            0.04,
            DiffuseMaterial(),
            UniformColors((0.9, 0.9, 0.88)),
            num_vertices=96,
            translation=(0, 0, -0.25),
            tag="plate",
        )
        scene.lights.add_sun(3.0, rotation_mode="eulerXYZ", rotation=(35, 25, 0))
        scene.lights.set_background_light(0.35)
    elif panel == "materials":
        for i, (mat, col) in enumerate(
            [
                (MetalMaterial(roughness=0.25, metallic=1.0), (0.9, 0.75, 0.4)),
                (PlasticMaterial(), ICING),
                (PlasticWireframeMaterial(wireframe_thickness=0.004, wireframe_color=(0.05, 0.05, 0.05)), DOUGH),
            ]
        ):
            r.add_mesh(
                v * 0.55, f, mat, UniformColors(col), smooth=True, translation=((i - 1) * 0.75, 0, 0), tag=f"donut_{i}"
            )
        r.add_plane_mesh(
            6.0, DiffuseMaterial(), UniformColors((0.85, 0.85, 0.85)), translation=(0, 0, -0.14), tag="floor"
        )
        scene.lights.add_area(
            "square", 1.5, strength=120.0, rotation_mode="look_at", rotation=(0, 0, 0), translation=(0.8, -1.2, 2.0)
        )
        scene.lights.set_background_light(0.4)
        cam_pos, target = (0.0, -2.2, 1.2), (0.0, 0.0, 0.0)
    elif panel == "pointcloud":
        rng = np.random.default_rng(0)
        idx = rng.choice(len(v), size=min(6000, len(v)), replace=False)
        r.add_pointcloud(v[idx], DiffuseMaterial(), VertexColors(c[idx]), point_size=0.018, tag="points")
        scene.lights.add_sun(3.0, rotation_mode="eulerXYZ", rotation=(35, 25, 0))
        scene.lights.set_background_light(0.4)
    elif panel == "lighting":
        r.add_mesh(v, f, PrincipledBSDFMaterial(roughness=0.45), VertexColors(c), smooth=True, tag="donut")
        r.add_plane_mesh(
            6.0,
            DiffuseMaterial(),
            UniformColors((1, 1, 1)),
            shadow_catcher=True,
            translation=(0, 0, -0.22),
            tag="catcher",
        )
        scene.lights.add_spot(
            300.0,
            spot_size=np.deg2rad(50),
            spot_blend=0.3,
            rotation_mode="look_at",
            rotation=(0, 0, 0),
            translation=(-1.2, -0.8, 2.2),
            color=(1.0, 0.85, 0.7),
        )
        scene.lights.add_area(
            "rectangle",
            (0.6, 0.3),
            strength=60.0,
            rotation_mode="look_at",
            rotation=(0, 0, 0),
            translation=(1.4, -0.6, 1.0),
            color=(0.6, 0.75, 1.0),
        )
        scene.lights.set_background_light(0.15)
    else:
        raise ValueError(f"panel: expected color, materials, pointcloud or lighting, got {panel!r}")
    scene.set_perspective_camera(
        resolution,
        fov_x=np.deg2rad(42),
        rotation_mode="look_at",
        rotation=np.asarray(target, float),
        translation=cam_pos,
    )
    return scene


def _label(img: np.ndarray, text: str) -> np.ndarray:
    from PIL import Image, ImageDraw

    im = Image.fromarray(img).convert("RGB")
    canvas = Image.new("RGB", (im.width, im.height + 22), (255, 255, 255))
    canvas.paste(im, (0, 22))
    ImageDraw.Draw(canvas).text((6, 4), text, fill=(20, 20, 20))
    return np.asarray(canvas)


def _over_white(result: RenderResult) -> UInt8Array:
    rgba = result.to_srgb8().astype(np.float32) / 255.0
    a = rgba[..., 3:4]
    return np.round((rgba[..., :3] * a + (1 - a)) * 255).astype(np.uint8)


def run_demo(
    output: str | Path = "blendify_demo.png",
    backend: str | None = None,
    quality: str = "draft",
    size: int = 256,
    samples: int | None = None,
    log: Callable[[str], object] = print,
) -> Path:
    """Render the demo panels and write a labelled contact sheet; returns its path."""
    from PIL import Image

    panels: list[np.ndarray] = []
    res = (size, size)
    t0 = time.perf_counter()
    main = render(
        donut_scene("color", res), backend=backend, quality=quality, samples=samples, outputs=("rgb", "depth", "albedo")
    )
    used = main.meta["backend"]
    seconds = main.meta["timings"]["total"]
    log(f"demo: rendering with backend {used!r} ({quality}); {seconds:.1f} s for colour+depth+albedo")
    panels.append(_label(_over_white(main), f"colour ({used})"))
    if main.depth is None or main.albedo is None:
        raise RenderError(f"demo: backend {used!r} returned no depth or albedo although both were requested")
    panels.append(_label(np.dstack([depth_to_image(main.depth)] * 3), "depth"))
    panels.append(_label(linear_to_srgb8(main.albedo), "albedo"))
    for panel, label in (
        ("materials", "metal / plastic / wireframe"),
        ("pointcloud", "point cloud"),
        ("lighting", "spot + area light, shadow catcher"),
    ):
        result = render(donut_scene(panel, res), backend=used, quality=quality, samples=samples)
        log(f"demo: {panel} {result.meta['timings']['total']:.1f} s")
        for approx in result.meta.get("approximations", []):
            log(f"demo:   approximated: {approx}")
        panels.append(_label(_over_white(result), label))
    h = max(p.shape[0] for p in panels)
    w = max(p.shape[1] for p in panels)
    sheet = np.full((2 * h, 3 * w, 3), 255, np.uint8)
    for i, p in enumerate(panels):
        y, x = divmod(i, 3)
        sheet[y * h : y * h + p.shape[0], x * w : x * w + p.shape[1]] = p
    out = Path(output)
    atomic_write(out, lambda tmp: Image.fromarray(sheet).save(tmp, format="PNG"))
    log(f"demo: wrote {out} ({time.perf_counter() - t0:.1f} s in all)")
    return out
