"""Files at full precision in every backend: a Radiance .hdr environment keeps values above 1, a 16-bit PNG
texture keeps steps below 8 bits (Cycles reads it with Blender's loader, Mitsuba and pyrender from the
IR's decoder; pyrender, a raster preview, uploads textures as 8-bit sRGB and says so)."""

from __future__ import annotations

import numpy as np
import pytest

import blendify_core as bf
from blendify_core.testing import write_png16, write_radiance_hdr

SKY = (3.0, 1.5, 0.25)


def test_hdr_environment_keeps_values_above_one(backend, tmp_path):
    vals = np.broadcast_to(np.array(SKY), (8, 16, 3)).copy()
    scene = bf.Scene()
    scene.lights.set_environment_map(write_radiance_hdr(tmp_path / "sky.hdr", vals))
    scene.set_perspective_camera((8, 6), fov_x=np.deg2rad(40))
    result = bf.render(scene, backend, samples=2, seed=0, transparent_background=False)
    # RGBE stores 8 bits of the largest channel: within 3/256 of the written values, all above 8-bit range
    np.testing.assert_allclose(result.rgba[..., :3], np.broadcast_to(SKY, (6, 8, 3)), atol=3.0 / 256 + 1e-4)


def test_16bit_png_texture_keeps_steps_below_8_bits(backend, tmp_path):
    low, high = 30000, 30070  # 70 / 65535 = 0.0011 apart: both are the same 8-bit value
    values = np.array([[[low] * 3, [high] * 3]], dtype=np.uint16)
    path = write_png16(tmp_path / "t.png", values, filters=(1,))
    scene = bf.Scene()
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
    uv = bf.VertexUV(np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float))
    colors = bf.FileTextureColors(str(path), uv, color_space="linear", interpolation="closest")
    scene.renderables.add_mesh(v, [[0, 1, 2, 3]], bf.DiffuseMaterial(), colors)
    scene.set_perspective_camera((8, 4), fov_x=np.deg2rad(40), translation=(0, 0, 3))
    scene.lights.set_background_light(1.0)
    result = bf.render(scene, backend, samples=2, seed=0, outputs=("rgb", "albedo"))
    left, right = result.albedo[2, 1, 0], result.albedo[2, 6, 0]
    if backend == "pyrender":
        note = bf.get_backend_class("pyrender").capabilities()["mesh.file_texture"].note
        assert "8-bit sRGB" in note, "pyrender must say that it uploads textures as 8-bit sRGB"
        # one 8-bit sRGB level near 0.46 linear is ~0.0035 wide: both texels land within it
        assert abs(left - low / 65535) < 0.004 and abs(right - high / 65535) < 0.004
        return
    assert left == pytest.approx(low / 65535, abs=2e-5) and right == pytest.approx(high / 65535, abs=2e-5)
