"""render_many with a real engine in the worker processes (pyrender, else Mitsuba): the frames are the
light-unit plane and come out right, and a second run skips them. Skips, printing why, when neither
backend is available."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

import blendify_core as bf
from blendify_core.testing import plane_scene


def _backend() -> str:
    status = bf.available_backends()
    for name in ("pyrender", "mitsuba"):
        if name in status and status[name].available:
            return name
    reasons = "; ".join(
        f"{n}: {status[n].reason if n in status else 'not registered'}" for n in ("pyrender", "mitsuba")
    )
    print(f"skipping the real-backend batch test: {reasons}")
    pytest.skip(f"neither pyrender nor mitsuba is available ({reasons})")


def test_render_many_with_a_real_backend(tmp_path):
    name = _backend()
    albedos = (0.3, 0.5, 0.8)
    jobs = [
        bf.RenderJob(plane_scene("sun", (32, 32), albedo=a), tmp_path / f"plane{i}.npz", backend=name, samples=4)
        for i, a in enumerate(albedos)
    ]
    report = bf.render_many(jobs, workers=2, timeout=120, progress=False)
    print(report.summary())
    assert report.statuses == ["done"] * 3, report.summary()
    assert {j.backend for j in report} == {name}
    # Lambertian plane under a 3 W/m^2 sun tilted by 20 degrees: L = albedo / pi * 3 * cos(20 deg)
    for a, j in zip(albedos, report):
        with np.load(j.output) as data:
            rgba = data["rgba"]
        assert rgba.shape == (32, 32, 4)
        expected = a / np.pi * 3.0 * np.cos(np.deg2rad(20.0))
        assert np.median(rgba[..., :3]) == pytest.approx(expected, rel=0.05)
    assert bf.render_many(jobs, workers=2, progress=False).statuses == ["skipped"] * 3


@pytest.mark.slow
def test_unguarded_script_on_stdin_with_a_real_backend(tmp_path):
    """The same frames from code fed to ``python -`` without a main guard: the workers start the real
    engine without re-running the caller's code."""
    name = _backend()
    code = (
        "import sys\n"
        "import blendify_core as bf\n"
        "from blendify_core.testing import plane_scene\n"
        "scenes = [plane_scene('sun', (32, 32), albedo=a) for a in (0.3, 0.8)]\n"
        f"jobs = [bf.RenderJob(s, f'plane{{i}}.npz', backend={name!r}, samples=4) for i, s in enumerate(scenes)]\n"
        "report = bf.render_many(jobs, workers=2, timeout=120, progress=False)\n"
        "print(report.summary())\n"
        "sys.exit(0 if report.ok else 1)\n"
    )
    proc = subprocess.run([sys.executable, "-"], input=code, cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr[-3000:]
    assert "2 jobs: 2 done" in proc.stdout and "Traceback" not in proc.stderr
    for i, a in enumerate((0.3, 0.8)):
        with np.load(tmp_path / f"plane{i}.npz") as data:
            rgba = data["rgba"]
        expected = a / np.pi * 3.0 * np.cos(np.deg2rad(20.0))
        assert np.median(rgba[..., :3]) == pytest.approx(expected, rel=0.05)
