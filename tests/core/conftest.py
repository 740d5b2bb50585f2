"""Fixtures of the core tests: a fake backend (core_fake_backend.py) registered through the public
registry, and a small scene factory."""

from __future__ import annotations

import numpy as np
import pytest
from core_fake_backend import FakeBackend, close_fake_instances

import blendify_core as bf
from blendify_core.registry import register_backend, unregister_backend


@pytest.fixture
def fake_backend():
    """Register FakeBackend as "fake" (and as "cycles"/"pyrender"/"mitsuba" look-alikes on demand);
    everything is unregistered and the shared instances are closed afterwards."""
    from blendify_core import registry as backend_mod

    register_backend("fake", FakeBackend)
    saved_overrides, saved_available = dict(FakeBackend.overrides), FakeBackend.available
    FakeBackend.instances = []
    yield FakeBackend
    close_fake_instances()
    FakeBackend.overrides = saved_overrides
    FakeBackend.available = saved_available
    unregister_backend("fake")
    assert "fake" not in backend_mod._registered


def _simple_scene(resolution=(32, 24), lights: bool = True) -> bf.Scene:
    scene = bf.Scene()
    scene.renderables.add_sphere_nurbs(
        0.5, bf.DiffuseMaterial(), bf.UniformColors((0.5, 0.5, 0.5)), translation=(0, 0, 0), tag="ball"
    )
    scene.set_perspective_camera(resolution, fov_x=np.deg2rad(40), translation=(0, 0, 4))
    if lights:
        scene.lights.add_point(100.0, translation=(0, 2, 3))
    return scene


@pytest.fixture
def simple_scene():
    """Factory: a grey sphere at the origin, a camera at (0, 0, 4) looking down -Z, a point light."""
    return _simple_scene
