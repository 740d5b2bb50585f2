"""render_many with the default local process pool (2 workers) on a fake backend that can succeed,
fail, sleep past the timeout or kill its own worker process, job by job."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest
from batch_fake_backend import FAKE, TARGET, expected_red, tiny_scene
from PIL import Image

import blendify_core as bf
from blendify_core.batch.jobs import read_jobs
from blendify_core.batch.manifest import MANIFEST_NAME, Manifest
from blendify_core.errors import BlendifyError, InvalidSceneError
from blendify_core.registry import register_backend, unregister_backend

HERE = Path(__file__).resolve().parent


@pytest.fixture(autouse=True)
def fake_backend():
    register_backend(FAKE, TARGET)
    yield
    unregister_backend(FAKE)
    bf.close_backends()


def job(tmp: Path, tag: str, action: str = "ok", **kw) -> bf.RenderJob:
    log = str(tmp / "renders.log")
    return bf.RenderJob(tiny_scene(tag), tmp / "out" / f"{tag}.png", backend=FAKE, action=action, log=log, **kw)


def render_log(tmp: Path) -> list[tuple[int, str, str]]:
    p = tmp / "renders.log"
    if not p.exists():
        return []
    return [(int(a), b, c) for a, b, c in (line.split() for line in p.read_text().splitlines())]


def manifest_records(path: Path) -> list[dict]:
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


def leftovers(folder: Path) -> list[str]:
    """Temporary files of interrupted atomic writes."""
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


def test_statuses_reasons_crashes_and_timeout(tmp_path):
    actions = ["ok", "raise", "kill", "ok", "abort", "sleep", "ok", "segfault", "ok"]
    jobs = [job(tmp_path, f"j{i}", a, seconds=60) for i, a in enumerate(actions)]
    t0 = time.monotonic()
    report = bf.render_many(jobs, workers=2, timeout=2.0, progress=False)
    elapsed = time.monotonic() - t0
    print(report.summary())
    assert elapsed < 40, "the sleeping job must be killed at its timeout, not waited for"
    assert report.statuses == ["done" if a == "ok" else "failed" for a in actions], report.summary()
    reasons = {j.index: j.reason for j in report.failed}
    assert "RenderError" in reasons[1] and "fake engine failure" in reasons[1]
    assert "worker crashed" in reasons[2] and "SIGKILL" in reasons[2]
    assert "worker crashed" in reasons[4] and "SIGABRT" in reasons[4]
    assert reasons[5].startswith("timeout") and "2 s" in reasons[5]
    assert "worker crashed" in reasons[7] and "SIGSEGV" in reasons[7]
    assert report.executor == "local" and report.workers == 2 and not report.ok
    assert report.counts == {"done": 4, "skipped": 0, "failed": 5}

    out = tmp_path / "out"
    for j in report.done:
        img = np.asarray(Image.open(j.output))
        assert img.shape == (12, 16, 4)
        tag = Path(j.output).stem
        assert int(img[0, 0, 0]) == expected_red(tag), "each output holds its own job's frame"
        assert j.files == [j.output] and j.worker and j.rss_mb and j.rss_mb > 10
    assert sorted(p.name for p in out.glob("*.png")) == sorted(f"j{i}.png" for i, a in enumerate(actions) if a == "ok")
    assert leftovers(out) == [], "no partial files from killed workers"

    # the manifest holds one record per job, consistent with the report
    records = manifest_records(out / MANIFEST_NAME)
    assert len(records) == len(jobs)
    by_key = {r["key"]: r for r in records}
    for st in report:
        assert by_key[st.key]["status"] == st.status and by_key[st.key]["output"] == st.output
        assert by_key[st.key]["reason"] == st.reason


def test_resume_skips_done_retries_failed_and_renders_each_output_once(tmp_path):
    flag = tmp_path / "fail.flag"
    flag.touch()
    # jobs 2 and 5 fail while the flag exists (a transient failure), the others succeed
    jobs = [job(tmp_path, f"j{i}", "raise_if_exists" if i in (2, 5) else "ok", path=str(flag)) for i in range(7)]
    first = bf.render_many(jobs[:4], workers=2, progress=False)  # an "interrupted" run: only part of the batch
    assert first.statuses == ["done", "done", "failed", "done"]

    flag.unlink()
    second = bf.render_many(jobs, workers=2, progress=False)
    assert second.statuses == ["skipped", "skipped", "done", "skipped", "done", "done", "done"]
    assert second.skipped[0].files == [jobs[0].output]

    third = bf.render_many(jobs, workers=2, progress=False)
    assert third.statuses == ["skipped"] * 7 and third.workers == 0

    renders = Counter(tag for _, tag, _ in render_log(tmp_path))
    # every job rendered exactly once, except job 2 which failed once before succeeding
    assert renders == {f"j{i}": (2 if i == 2 else 1) for i in range(7)}
    records = manifest_records(tmp_path / "out" / MANIFEST_NAME)
    assert len(records) == 4 + 4  # 4 in the first run, 4 in the second, none in the third
    last = {r["key"]: r["status"] for r in records}
    assert list(last.values()).count("done") == 7 and len(last) == 7

    # an output deleted since is rendered again; a changed setting is a new job
    os.unlink(jobs[3].output)
    jobs[6] = job(tmp_path, "j6", "ok", path=str(flag), samples=3)
    fourth = bf.render_many(jobs, workers=2, progress=False)
    assert fourth.statuses == ["skipped"] * 3 + ["done", "skipped", "skipped", "done"]
    assert Path(jobs[3].output).is_file()


def test_interrupted_run_resumes_without_losing_or_duplicating_outputs(tmp_path):
    """Kill the driver of a CLI batch run mid-way (SIGKILL: no cleanup at all), then run it again."""
    scenes = tmp_path / "scenes"
    scenes.mkdir()
    lines = []
    for i in range(10):
        tiny_scene(f"k{i}").save(scenes / f"k{i}.npz")
        lines.append(
            json.dumps(
                {
                    "scene": f"scenes/k{i}.npz",
                    "output": f"out/k{i}.png",
                    "backend": FAKE,
                    "action": "sleep",
                    "seconds": 0.4,
                    "log": str(tmp_path / "renders.log"),
                }
            )
        )
    jobs_file = tmp_path / "jobs.jsonl"
    jobs_file.write_text("\n".join(lines) + "\n")
    code = (
        f"import sys; sys.path.insert(0, {str(HERE)!r})\n"
        "from blendify_core.registry import register_backend\n"
        f"register_backend({FAKE!r}, {TARGET!r})\n"
        "from blendify_core.cli.main import main\n"
        "if __name__ == '__main__':\n"
        f"    raise SystemExit(main(['batch', {str(jobs_file)!r}, '--workers', '2', '--no-progress']))\n"
    )
    script = tmp_path / "run_batch.py"
    script.write_text(code)
    manifest = tmp_path / "out" / MANIFEST_NAME
    proc = subprocess.Popen([sys.executable, str(script)], start_new_session=True)
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            if manifest.exists() and len(manifest.read_text().splitlines()) >= 3:
                break
            time.sleep(0.05)
        else:
            pytest.fail("the batch run did not finish 3 jobs in 60 s")
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=10)
        # the orphaned workers exit on their own once the driver is gone
        time.sleep(1.5)
    finally:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    done_before = {r["output"] for r in manifest_records(manifest) if r["status"] == "done"}
    assert 3 <= len(done_before) < 10

    jobs = read_jobs(jobs_file)
    report = bf.render_many(jobs, workers=2, progress=False)
    skipped = {j.output for j in report.skipped}
    assert skipped == done_before
    assert report.counts["failed"] == 0 and report.counts["done"] == 10 - len(done_before)
    out = tmp_path / "out"
    assert sorted(p.name for p in out.glob("*.png")) == [f"k{i}.png" for i in range(10)]
    assert leftovers(out) == []
    renders = Counter(tag for _, tag, _ in render_log(tmp_path))
    for i in range(10):
        path = str(out / f"k{i}.png")
        # finished before the kill: never rendered again; otherwise at most once per run
        assert renders[f"k{i}"] == 1 if path in done_before else 1 <= renders[f"k{i}"] <= 2
    records = manifest_records(manifest)
    assert {r["output"] for r in records if r["status"] == "done"} == {str(out / f"k{i}.png") for i in range(10)}
    assert all(r["status"] == "done" for r in records)


def test_ctrl_c_stops_the_workers_and_keeps_the_manifest(tmp_path):
    rows = []
    for i in range(6):
        tiny_scene(f"i{i}").save(tmp_path / f"i{i}.npz")
        rows.append(
            {
                "scene": f"i{i}.npz",
                "output": f"o/i{i}.png",
                "backend": FAKE,
                "action": "sleep",
                "seconds": 30,
                "log": str(tmp_path / "renders.log"),
            }
        )
    rows[0].update(action="ok")
    (tmp_path / "jobs.jsonl").write_text("\n".join(json.dumps(r) for r in rows))
    script = tmp_path / "run.py"
    script.write_text(
        f"import sys; sys.path.insert(0, {str(HERE)!r})\n"
        "from blendify_core.registry import register_backend\n"
        f"register_backend({FAKE!r}, {TARGET!r})\n"
        "from blendify_core.cli.main import main\n"
        "if __name__ == '__main__':\n"
        f"    raise SystemExit(main(['batch', {str(tmp_path / 'jobs.jsonl')!r}, '-w', '2', '--no-progress']))\n"
    )
    proc = subprocess.Popen([sys.executable, str(script)], stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60
        while len(render_log(tmp_path)) < 3 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert len(render_log(tmp_path)) >= 3, "the workers did not start"
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130 and "interrupted" in err
    time.sleep(0.5)
    for pid in {pid for pid, _, _ in render_log(tmp_path)}:
        with pytest.raises(ProcessLookupError):
            os.kill(pid, 0)  # every worker is gone
    records = manifest_records(tmp_path / "o" / MANIFEST_NAME)
    assert [r["status"] for r in records] == ["done"] and records[0]["output"].endswith("i0.png")
    assert leftovers(tmp_path / "o") == []


def test_workers_are_recycled_after_n_jobs_which_bounds_a_leak(tmp_path):
    leak = 40.0  # MiB the fake engine keeps per render
    jobs = [job(tmp_path, f"r{i}", leak_mb=leak) for i in range(8)]
    report = bf.render_many(jobs, workers=2, recycle_after=2, progress=False, manifest=False)
    assert report.ok
    per_worker = Counter(j.worker for j in report)
    assert len(per_worker) >= 4 and max(per_worker.values()) <= 2, per_worker
    pids = Counter(pid for pid, _, _ in render_log(tmp_path))
    assert pids == Counter({int(w.split(":")[1]): n for w, n in per_worker.items()})
    base = min(j.rss_mb for j in report)
    assert max(j.rss_mb for j in report) < base + 1.5 * leak  # at most 2 leaks per process

    jobs = [job(tmp_path, f"s{i}", leak_mb=leak) for i in range(6)]
    report = bf.render_many(jobs, workers=2, recycle_after=None, progress=False, manifest=False)
    assert len({j.worker for j in report}) <= 2
    assert max(j.rss_mb for j in report) > base + 1.8 * leak  # without recycling the leak accumulates

    # a memory limit instead of a job count: a worker is replaced after the job that crossed it
    jobs = [job(tmp_path, f"q{i}", leak_mb=leak) for i in range(6)]
    report = bf.render_many(
        jobs, workers=1, recycle_after=None, recycle_above_mb=base + 0.5 * leak, progress=False, manifest=False
    )
    assert report.ok and len({j.worker for j in report}) == 3
    assert max(j.rss_mb for j in report) < base + 1.5 * leak


def test_engine_threads_do_not_oversubscribe(tmp_path):
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    jobs = [job(tmp_path, f"t{i}") for i in range(2)] + [job(tmp_path, "t9", threads=1)]
    assert bf.render_many(jobs, workers=1, progress=False, manifest=False).ok
    threads = {tag: t for _, tag, t in render_log(tmp_path)}
    assert threads == {"t0": str(cores), "t1": str(cores), "t9": "1"}


def test_cli_batch(tmp_path, capsys):
    from blendify_core.cli.main import main

    (tmp_path / "sc").mkdir()
    rows = []
    for i, action in enumerate(["ok", "ok", "raise"]):
        tiny_scene(f"c{i}").save(tmp_path / "sc" / f"c{i}.npz")
        rows.append({"scene": f"sc/c{i}.npz", "output": f"o/c{i}.npz", "backend": FAKE, "action": action})
    rows[1]["outputs"] = ["rgb", "depth"]
    path = tmp_path / "jobs.jsonl"
    path.write_text("# a comment\n" + "\n".join(json.dumps(r) for r in rows) + "\n\n")
    code = main(["batch", str(path), "--workers", "2", "--timeout", "30", "--recycle", "5", "--no-progress"])
    out = capsys.readouterr().out
    assert code == 1, "a failed job makes the exit code 1"
    assert "3 jobs: 2 done, 0 skipped, 1 failed" in out and "fake engine failure" in out
    with np.load(tmp_path / "o" / "c1.npz") as data:
        assert data["rgba"].shape == (12, 16, 4) and np.all(data["depth"] == 2.0)

    path.write_text("\n".join(json.dumps(r) for r in rows[:2]) + "\n")
    assert main(["batch", str(path), "--no-progress"]) == 0
    assert "2 jobs: 0 done, 2 skipped, 0 failed" in capsys.readouterr().out

    path.write_text('{"scene": "sc/c0.npz"}\n')
    assert main(["batch", str(path)]) == 2  # a bad jobs file is bad input (the CLI's exit-code table)
    assert "missing 'output'" in capsys.readouterr().err
    assert main(["batch", str(tmp_path / "nope.jsonl")]) == 2


def test_png_outputs_write_one_file_per_requested_output(tmp_path):
    j = job(tmp_path, "m0", outputs=("rgb", "depth"))
    report = bf.render_many([j], workers=1, progress=False)
    assert report.ok
    files = report[0].files
    assert [Path(f).name for f in files] == ["m0.png", "m0.depth.png"] and all(Path(f).is_file() for f in files)
    os.unlink(files[1])  # one of the job's files lost: the job is not finished any more
    assert bf.render_many([j], workers=1, progress=False).statuses == ["done"]


def test_thread_pool_executor_and_soft_timeout(tmp_path):
    """Any concurrent.futures executor works; it cannot kill a task, so an overrunning job is failed and
    writes nothing."""
    jobs = [job(tmp_path, "f0"), job(tmp_path, "f1", "raise"), job(tmp_path, "f2", "sleep", seconds=2.5)]
    with ThreadPoolExecutor(2) as ex:
        report = bf.render_many(jobs, executor=ex, timeout=1.0, progress=False)
    assert report.statuses == ["done", "failed", "failed"]
    assert report.executor == "ThreadPoolExecutor" and report.workers == 2
    assert "fake engine failure" in report[1].reason
    assert report[2].reason.startswith("timeout") and "not written" in report[2].reason
    assert not Path(jobs[2].output).exists()
    assert Path(jobs[0].output).is_file()


def test_json_manifest_and_no_manifest(tmp_path):
    jobs = [job(tmp_path, f"n{i}") for i in range(2)]
    man = tmp_path / "state" / "batch.json"
    assert bf.render_many(jobs, workers=1, manifest=man, progress=False).statuses == ["done", "done"]
    doc = json.loads(man.read_text())
    assert doc["format"] == "blendify-batch-manifest" and len(doc["jobs"]) == 2
    assert bf.render_many(jobs, workers=1, manifest=man, progress=False).statuses == ["skipped", "skipped"]
    assert bf.render_many(jobs, workers=1, manifest=False, progress=False).statuses == ["done", "done"]


def test_manifest_is_locked_and_survives_a_torn_line(tmp_path):
    path = tmp_path / "m.jsonl"
    path.write_text('{"key": "a", "status": "done", "files": []}\n{"key": "b", "sta')  # killed mid-write
    m = Manifest(path)
    try:
        assert set(m.records) == {"a"}
        with pytest.raises(BlendifyError, match="in use by another render_many"):
            Manifest(path)
        m.add({"key": "c", "status": "failed"})
    finally:
        m.close()
    m2 = Manifest(path)
    assert set(m2.records) == {"a", "c"}
    m2.close()


def test_unreadable_scene_fails_its_job_only(tmp_path):
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip")
    jobs = [bf.RenderJob(bad, tmp_path / "out" / "bad.png", backend=FAKE), job(tmp_path, "u1")]
    report = bf.render_many(jobs, workers=1, progress=False)
    assert report.statuses == ["failed", "done"]
    assert "not a readable scene file" in report[0].reason


def test_bad_input_is_rejected_with_the_argument_name(tmp_path):
    s = tiny_scene("v")
    with pytest.raises(InvalidSceneError, match="output"):
        bf.RenderJob(s, tmp_path / "a.jpg")
    with pytest.raises(InvalidSceneError, match="scene_or_path"):
        bf.RenderJob(42, tmp_path / "a.png")
    with pytest.raises(InvalidSceneError, match="scene_or_path"):
        bf.RenderJob(tmp_path / "scene.obj", tmp_path / "a.png")
    with pytest.raises(InvalidSceneError, match="samples"):
        bf.RenderJob(s, tmp_path / "a.png", samples=0)
    with pytest.raises(InvalidSceneError, match="JSON"):
        bf.RenderJob(s, tmp_path / "a.png", backend=FAKE, log=object())
    with pytest.raises(InvalidSceneError, match="backend"):
        bf.RenderJob(s, tmp_path / "a.png", backend=bf.get_backend(FAKE))
    jobs = [bf.RenderJob(s, tmp_path / "a.png"), bf.RenderJob(s, tmp_path / "a.png", samples=4)]
    with pytest.raises(InvalidSceneError, match=r"jobs\[1\].*also written by jobs\[0\]"):
        bf.render_many(jobs, progress=False)
    with pytest.raises(InvalidSceneError, match="jobs"):
        bf.render_many([s], progress=False)
    with pytest.raises(InvalidSceneError, match="workers"):
        bf.render_many(jobs[:1], workers=0, progress=False)
    with pytest.raises(InvalidSceneError, match="timeout"):
        bf.render_many(jobs[:1], timeout=-1, progress=False)
    with pytest.raises(InvalidSceneError, match="recycle_above_mb"):
        bf.render_many(jobs[:1], recycle_above_mb=0, progress=False)
    with pytest.raises(InvalidSceneError, match="recycle_after"):
        bf.render_many(jobs[:1], recycle_after=0, progress=False)
    with pytest.raises(InvalidSceneError, match="executor"):
        bf.render_many(jobs[:1], executor="slurm", progress=False)
    assert len(bf.render_many([], progress=False)) == 0


@pytest.mark.parametrize(
    "init, expected, most_starts",
    [
        ("raise SystemExit(3)\n", "exited with code 3", 4),  # dies silently: retried, then given up
        ("raise ImportError('broken install')\n", "ImportError: broken install", 2),  # not retried
    ],
)
def test_workers_that_cannot_start_fail_the_jobs_without_hanging(tmp_path, capfd, init, expected, most_starts):
    """Workers take this process's sys.path: a broken ``blendify_core`` first on it kills every worker
    while it starts. The jobs fail with the reason, once workers plainly cannot start no more are tried."""
    shadow = tmp_path / "shadow"
    (shadow / "blendify_core").mkdir(parents=True)
    (shadow / "blendify_core" / "__init__.py").write_text(f"import sys\nsys.stderr.write('worker start\\n')\n{init}")
    jobs = [job(tmp_path, t) for t in "abcdef"]
    sys.path.insert(0, str(shadow))
    try:
        t0 = time.monotonic()
        report = bf.render_many(jobs, workers=2, progress=False, manifest=False)
    finally:
        sys.path.remove(str(shadow))
    assert time.monotonic() - t0 < 60
    assert report.counts["failed"] == 6 and render_log(tmp_path) == []
    for r in report:
        assert "worker failed to start" in r.reason and expected in r.reason, r.reason
    err = capfd.readouterr().err
    assert 2 <= err.count("worker start") <= most_starts, err[-3000:]


def test_blender_script_folders_of_the_parent_do_not_shadow_bpy_in_workers(tmp_path):
    """After ``import bpy`` the parent's sys.path starts with bpy/<version>/scripts/modules, which holds a
    pure-Python ``bpy`` package; spawned workers inherit it and must drop it (else "No module named _bpy")."""
    shadow = tmp_path / "site" / "bpy" / "5.0" / "scripts" / "modules"
    (shadow / "bpy").mkdir(parents=True)
    (shadow / "bpy" / "__init__.py").write_text("from _bpy import types\n")
    sys.path.insert(0, str(shadow))
    try:
        report = bf.render_many([job(tmp_path, "b0", "check_sys_path")], workers=1, progress=False)
    finally:
        sys.path.remove(str(shadow))
    assert report.statuses == ["done"], report.summary()
