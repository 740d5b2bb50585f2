"""Fixtures of the utils tests: a fake backend whose image depends on the camera pose (no engine)."""

from __future__ import annotations

import numpy as np
import pytest

import blendify_core as bf
from blendify_core.pipeline.backend import Backend
from blendify_core.pipeline.capabilities import ALL_FEATURES, Capability
from blendify_core.pipeline.result import RenderResult
from blendify_core.registry import register_backend, unregister_backend


class PoseColourBackend(Backend):
    """Renders a flat image whose colour encodes the camera position, with a transparent left column.
    Counts its translate/render calls so tests can check instance reuse."""

    name = "fake_pose_colour"
    engine = None
    instances: list[PoseColourBackend] = []

    def __init__(self, **options):
        super().__init__(**options)
        self.renders = 0
        PoseColourBackend.instances.append(self)

    @classmethod
    def capabilities(cls):
        return {f: Capability("exact") for f in ALL_FEATURES}

    def translate(self, scene, settings):
        cam = scene.camera
        return {"res": (cam.width, cam.height), "t": np.array(cam.translation), "outputs": settings.outputs}

    def render(self, native, settings):
        self.renders += 1
        w, h = native["res"]
        c = np.clip(0.5 + 0.1 * native["t"], 0.0, 1.0).astype(np.float32)
        rgba = np.empty((h, w, 4), np.float32)
        rgba[..., :3] = c
        rgba[..., 3] = 1.0
        rgba[:, 0] = 0.0  # a transparent column (premultiplied)
        depth = (
            np.full((h, w), float(np.linalg.norm(native["t"])), np.float32) if "depth" in native["outputs"] else None
        )
        return RenderResult(rgba=rgba, depth=depth, meta={"timings": {}})


@pytest.fixture
def fake_backend():
    register_backend(PoseColourBackend.name, PoseColourBackend)
    PoseColourBackend.instances.clear()
    yield PoseColourBackend
    bf.close_backends()
    unregister_backend(PoseColourBackend.name)


@pytest.fixture
def small_scene():
    scene = bf.Scene()
    scene.set_perspective_camera(
        (24, 16), fov_x=0.8, rotation_mode="look_at", rotation=(0, 0, 0), translation=(0, -3, 1)
    )
    scene.renderables.add_cube_mesh(1.0, bf.DiffuseMaterial(), bf.UniformColors((0.8, 0.2, 0.2)))
    scene.lights.add_sun(strength=2.0)
    return scene


@pytest.fixture
def open3d():
    """Open3D (the optional `mesh` extra); skips with the import error when it is missing or cannot load
    (its wheel needs the system library libusb-1.0, absent on a fresh machine)."""
    try:
        import open3d as o3d
    except ImportError as exc:
        pytest.skip(f"Open3D (optional 'mesh' extra for meshify_pointcloud) unavailable: {exc}")
    return o3d
