"""bf.crosscheck and `blendify crosscheck` end to end with the real backends (whichever are available)."""

from __future__ import annotations

import numpy as np
import pytest
from xb_util import BACKENDS, backend_status

import blendify_core as bf
from blendify_core.evaluate.crosscheck import crosscheck_main
from blendify_core.testing import plane_scene


def available() -> list[str]:
    names = [b for b in BACKENDS if backend_status().get(b) is not None and backend_status()[b].available]
    if len(names) < 2:
        reason = f"crosscheck needs two available backends, have {names}"
        print(f"SKIP: {reason}")
        pytest.skip(reason)
    return names


def test_crosscheck_sun_plane_all_pairs_pass(artifacts_dir):
    names = available()
    rep = bf.crosscheck(plane_scene("sun", resolution=(32, 32)), samples=16, scene_name="plane_sun")
    print(rep)
    print(rep.summary())
    assert set(rep.results) == set(names)
    assert len(rep.pairs) == len(names) * (len(names) - 1) // 2
    for (a, b), pair in rep.pairs.items():
        assert pair.tier == ("pathtracer_delta" if {a, b} <= {"cycles", "mitsuba"} else "raster")
    assert rep.passed, rep.summary()
    sheet = rep.contact_sheet(tile=64)
    assert sheet.dtype == np.uint8 and sheet.shape[0] > 64 * (len(names) + len(rep.pairs))
    rep.save(artifacts_dir)
    assert (artifacts_dir / "crosscheck.png").exists()


def test_crosscheck_cli_on_a_scene_file(tmp_path, capsys):
    available()
    path = tmp_path / "plane.npz"
    plane_scene("point", resolution=(32, 32)).save(path)
    code = crosscheck_main([str(path), "-o", str(tmp_path / "out"), "--samples", "16", "--outputs", "rgb,depth"])
    out = capsys.readouterr().out
    print(out)
    assert code == 0, out
    assert (tmp_path / "out" / "crosscheck.png").exists()
    text = (tmp_path / "out" / "crosscheck.md").read_text()
    assert "PASS" in text and "| rgb | mean_rel_error |" in text
