"""`import blendify_core.utils` loads numpy/scipy only; optional libraries load on first use."""

from __future__ import annotations

import json
import subprocess
import sys

HEAVY = ("PIL", "tqdm", "imageio", "imageio_ffmpeg", "open3d", "trimesh", "skimage", "matplotlib", "bpy", "mitsuba")


def test_import_utils_loads_no_optional_library():
    code = (
        "import blendify_core, blendify_core.utils\n"
        "from blendify_core.utils import Trajectory, estimate_normals, render_frames, meshify_pointcloud\n"
        "import sys, json\nprint(json.dumps(sorted(sys.modules)))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    loaded = set(json.loads(out.stdout.strip().splitlines()[-1]))
    assert "blendify_core.utils.meshify" in loaded
    offenders = sorted(m for m in loaded if m.split(".")[0] in HEAVY)
    assert offenders == [], offenders
