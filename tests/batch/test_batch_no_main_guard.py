"""render_many's local pool from code that has no ``if __name__ == "__main__":`` guard: a script file,
the same code on stdin (``python -``), ``python -c`` and an IPython shell (what a notebook kernel runs).
Workers are fresh interpreters that never import ``__main__``; the one thing they cannot reach, a backend
class defined in ``__main__``, is refused once, up front, with what to do instead."""

from __future__ import annotations

import json
import logging
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest
from batch_fake_backend import FAKE, TARGET, FakeBackend, expected_red, tiny_scene
from PIL import Image

import blendify_core as bf
from blendify_core.batch import MANIFEST_NAME
from blendify_core.batch import worker as _worker
from blendify_core.errors import BlendifyError, InvalidSceneError
from blendify_core.registry import register_backend, unregister_backend

HERE = Path(__file__).resolve().parent
N_JOBS = 6

# no main guard anywhere: with multiprocessing's "spawn" every worker re-ran this and every job failed
UNGUARDED = f"""\
import json, os, sys
sys.path.insert(0, {str(HERE)!r})
import blendify_core as bf
from batch_fake_backend import FAKE, TARGET, tiny_scene
bf.register_backend(FAKE, TARGET)
jobs = [bf.RenderJob(tiny_scene(f"s{{i}}"), os.path.join("out", f"s{{i}}.png"), backend=FAKE) for i in range({N_JOBS})]
report = bf.render_many(jobs, workers=2, progress=False)
print("REPORT " + json.dumps({{"counts": report.counts, "workers": sorted({{j.worker for j in report}})}}))
"""


def run_python(mode: str, code: str, cwd: Path, name: str = "render_all.py") -> subprocess.CompletedProcess:
    if mode == "file":
        (cwd / name).write_text(code)
        cmd, stdin = [sys.executable, name], None
    elif mode == "stdin":
        cmd, stdin = [sys.executable, "-"], code
    elif mode == "-c":
        cmd, stdin = [sys.executable, "-c", code], None
    elif mode == "ipython":
        pytest.importorskip("IPython", reason="IPython is not installed: the notebook-kernel check needs it")
        cmd, stdin = [sys.executable, "-m", "IPython", "--no-banner", "--quick", "--colors=nocolor", "-c", code], None
    else:
        raise ValueError(mode)
    return subprocess.run(cmd, input=stdin, cwd=cwd, capture_output=True, text=True, timeout=180)


def report_of(proc: subprocess.CompletedProcess) -> dict:
    lines = [line for line in proc.stdout.splitlines() if line.startswith("REPORT ")]
    assert lines, f"no report printed\nstdout: {proc.stdout[-2000:]}\nstderr: {proc.stderr[-3000:]}"
    return json.loads(lines[-1][len("REPORT ") :])


@pytest.mark.parametrize("mode", ["file", "stdin", "-c", "ipython"])
def test_unguarded_code_renders_every_job(tmp_path, mode):
    proc = run_python(mode, UNGUARDED, tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "Traceback" not in proc.stderr and "in use" not in proc.stderr, proc.stderr[-3000:]
    rep = report_of(proc)
    assert rep["counts"] == {"done": N_JOBS, "skipped": 0, "failed": 0}
    assert len(rep["workers"]) == 2, "two worker processes rendered the jobs"
    out = tmp_path / "out"
    for i in range(N_JOBS):
        img = np.asarray(Image.open(out / f"s{i}.png"))
        assert img.shape == (12, 16, 4) and int(img[0, 0, 0]) == expected_red(f"s{i}")
    records = [json.loads(x) for x in (out / MANIFEST_NAME).read_text().splitlines()]
    assert [r["status"] for r in records] == ["done"] * N_JOBS

    if mode == "file":  # the unguarded script resumes like any other: a second run skips everything
        again = run_python(mode, UNGUARDED, tmp_path)
        assert again.returncode == 0 and report_of(again)["counts"]["skipped"] == N_JOBS, again.stderr[-3000:]


MAIN_CLASS = f"""\
import json, os, sys
sys.path.insert(0, {str(HERE)!r})
import blendify_core as bf
from batch_fake_backend import FakeBackend, tiny_scene

class Toy(FakeBackend):
    name = "toy"

bf.register_backend("toy", Toy)
jobs = [bf.RenderJob(tiny_scene(f"s{{i}}"), os.path.join("out", f"s{{i}}.png"), backend="toy") for i in range(8)]
report = bf.render_many(jobs, workers=2, progress=False)
print("REPORT " + json.dumps(report.counts))
"""


@pytest.mark.parametrize(("mode", "where"), [("file", "the script render_all.py"), ("-c", "`python -c`")])
def test_backend_class_defined_in_unguarded_main_gets_one_clear_error(tmp_path, mode, where):
    proc = run_python(mode, MAIN_CLASS, tmp_path)
    assert proc.returncode == 1 and "REPORT" not in proc.stdout
    err = proc.stderr
    assert err.count("Traceback") == 1, err  # raised once in the parent, no worker ever started
    last = err.strip().splitlines()[-1]
    assert last.startswith("blendify_core.errors.InvalidSceneError: jobs[0]: backend 'toy'"), last
    assert "class Toy defined in __main__" in last and where in last
    assert "bf.register_backend('toy', 'toy_backend:Toy')" in last and "ThreadPoolExecutor" in last
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())


def test_backend_path_that_names_the_running_script_is_refused(tmp_path):
    """Registering "script:Class" for the script being run would make every worker import, i.e. run, it."""
    code = MAIN_CLASS.replace('bf.register_backend("toy", Toy)', 'bf.register_backend("toy", "myjob:Toy")')
    proc = run_python("file", code, tmp_path, name="myjob.py")
    assert proc.returncode == 1 and proc.stderr.count("Traceback") == 1, proc.stderr
    last = proc.stderr.strip().splitlines()[-1]
    assert "'myjob:Toy'" in last and "the script myjob.py" in last and "run the script again" in last, last


def test_backend_class_defined_in_a_function_names_it_and_threads_still_work(tmp_path):
    class Local(FakeBackend):
        name = "local_fake"

    register_backend("local_fake", Local)
    try:
        jobs = [bf.RenderJob(tiny_scene(t), tmp_path / f"{t}.png", backend="local_fake") for t in ("a", "b")]
        with pytest.raises(InvalidSceneError, match=r"jobs\[0\]: backend 'local_fake'.*inside a function.*<locals>"):
            bf.render_many(jobs, progress=False)
        assert not list(tmp_path.glob("*.png"))
        # the alternative the message offers: render in this process, where the class is at hand
        with ThreadPoolExecutor(1) as ex:
            assert bf.render_many(jobs, executor=ex, progress=False).statuses == ["done", "done"]
    finally:
        unregister_backend("local_fake")
        bf.close_backends()


def test_render_many_refuses_to_start_a_pool_inside_its_own_worker(tmp_path, monkeypatch):
    """A module the workers import that starts a batch when imported must fail its jobs, not fork-bomb."""
    register_backend(FAKE, TARGET)
    monkeypatch.setattr(_worker, "_IN_POOL_WORKER", True)
    try:
        with pytest.raises(BlendifyError, match="inside one of render_many's own worker processes"):
            bf.render_many([bf.RenderJob(tiny_scene("w"), tmp_path / "w.png", backend=FAKE)], progress=False)
    finally:
        unregister_backend(FAKE)


def test_failed_jobs_do_not_look_like_success(tmp_path, capsys, caplog):
    from blendify_core.cli.main import main

    register_backend(FAKE, TARGET)
    try:
        (tmp_path / "sc").mkdir()
        rows = []
        for i in range(3):
            tiny_scene(f"f{i}").save(tmp_path / "sc" / f"f{i}.npz")
            rows.append({"scene": f"sc/f{i}.npz", "output": f"o/f{i}.png", "backend": FAKE, "action": "raise"})
        path = tmp_path / "jobs.jsonl"
        path.write_text("\n".join(json.dumps(r) for r in rows) + "\n")
        with caplog.at_level(logging.WARNING, logger="blendify_core"):
            code = main(["batch", str(path), "--workers", "2", "--no-progress"])
        assert code == 1, "a batch whose every job failed exits 1"
        assert "3 jobs: 0 done, 0 skipped, 3 failed" in capsys.readouterr().out
        warnings = [r.getMessage() for r in caplog.records if r.name == "blendify_core"]
        assert len(warnings) == 1 and warnings[0].startswith("render_many: 3 of 3 jobs failed (first: jobs[0]")
        assert "fake engine failure" in warnings[0]

        caplog.clear()
        rows = [{**r, "action": "ok"} for r in rows]
        path.write_text("\n".join(json.dumps(r) for r in rows) + "\n")
        with caplog.at_level(logging.WARNING, logger="blendify_core"):
            assert main(["batch", str(path), "--workers", "2", "--no-progress"]) == 0
        assert "3 jobs: 3 done, 0 skipped, 0 failed" in capsys.readouterr().out
        assert not [r for r in caplog.records if r.name == "blendify_core"], "no warning when every job is done"

        with pytest.raises(SystemExit) as exc:
            main(["batch", "--help"])
        assert exc.value.code == 0
        help_text = " ".join(capsys.readouterr().out.split())
        # the CLI's one exit-code table (blendify_core.errors.EXIT_CODES), with batch's own sentence
        assert "any failed job, even with others done, exits 1" in help_text
        assert "0 success (crosscheck: every pair agreed; batch: every job done or skipped)" in help_text
    finally:
        unregister_backend(FAKE)
        bf.close_backends()
