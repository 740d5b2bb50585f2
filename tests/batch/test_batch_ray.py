"""render_many(executor="ray") on a local single-machine Ray cluster with 2 CPUs (slow: starting Ray
takes 10-15 s here). Skips, printing why, when Ray is not installed (``pip install 'blendify-core[ray]'``)."""

from __future__ import annotations

import json
import os
from collections import Counter
from pathlib import Path

import pytest
from batch_fake_backend import FAKE, TARGET, tiny_scene

import blendify_core as bf
from blendify_core.batch.manifest import MANIFEST_NAME
from blendify_core.registry import register_backend, unregister_backend

# workers must use this interpreter, not `uv run` in a packaged copy of the checkout
os.environ.setdefault("RAY_ENABLE_UV_RUN_RUNTIME_ENV", "0")
try:
    import ray
except ImportError as exc:  # pragma: no cover - depends on the environment
    print(f"skipping the Ray batch tests: Ray is not installed ({exc})")
    pytest.skip(f"Ray is not installed ({exc}); pip install 'blendify-core[ray]'", allow_module_level=True)

pytestmark = pytest.mark.slow
HERE = Path(__file__).resolve().parent


@pytest.fixture(scope="module")
def ray_cluster():
    started = not ray.is_initialized()
    if started:
        # the workers must import the fake backend module from this folder
        ray.init(
            num_cpus=2,
            include_dashboard=False,
            log_to_driver=False,
            runtime_env={"env_vars": {"PYTHONPATH": str(HERE)}},
        )
    yield
    if started:
        ray.shutdown()


@pytest.fixture(autouse=True)
def fake_backend(ray_cluster):
    register_backend(FAKE, TARGET)
    yield
    unregister_backend(FAKE)


def job(tmp: Path, tag: str, action: str = "ok", **kw) -> bf.RenderJob:
    return bf.RenderJob(tiny_scene(tag), tmp / "out" / f"{tag}.png", backend=FAKE, action=action, **kw)


def test_ray_statuses_crash_timeout_and_resume(tmp_path):
    actions = ["ok", "raise", "kill", "sleep", "ok", "abort", "ok"]
    jobs = [job(tmp_path, f"y{i}", a, seconds=60) for i, a in enumerate(actions)]
    report = bf.render_many(jobs, executor="ray", timeout=3.0, progress=False)
    print(report.summary())
    assert report.executor == "ray" and report.workers == 2
    assert report.statuses == ["done" if a == "ok" else "failed" for a in actions]
    reasons = {j.index: j.reason for j in report.failed}
    assert "fake engine failure" in reasons[1]
    assert "worker crashed" in reasons[2] and "worker crashed" in reasons[5]
    assert reasons[3].startswith("timeout") and "3 s" in reasons[3]
    out = tmp_path / "out"
    assert sorted(p.name for p in out.glob("*.png")) == ["y0.png", "y4.png", "y6.png"]
    assert [p.name for p in out.iterdir() if p.name.startswith(".")] == []

    # resume: the finished jobs are skipped, the failed ones are tried again
    jobs[1] = job(tmp_path, "y1", "raise")  # a different job now (options changed)
    again = bf.render_many(jobs[:3], executor="ray", progress=False)
    assert again.statuses == ["skipped", "failed", "failed"]
    records = [json.loads(x) for x in (out / MANIFEST_NAME).read_text().splitlines()]
    assert len(records) == len(actions) + 2


def test_ray_recycles_workers_and_takes_scene_files(tmp_path):
    scenes = tmp_path / "scenes"
    scenes.mkdir()
    jobs = []
    for i in range(6):
        tiny_scene(f"z{i}").save(scenes / f"z{i}.npz")
        jobs.append(bf.RenderJob(scenes / f"z{i}.npz", tmp_path / "out" / f"z{i}.npz", backend=FAKE))
    report = bf.render_many(jobs, executor="ray", recycle_after=2, progress=False)
    assert report.ok, report.summary()
    per_worker = Counter(j.worker for j in report)
    assert len(per_worker) >= 3 and max(per_worker.values()) <= 2, per_worker
    assert all(Path(j.output).is_file() for j in report)


def test_cli_batch_with_ray(tmp_path, capsys):
    from blendify_core.cli.main import main

    (tmp_path / "sc").mkdir()
    rows = []
    for i in range(3):
        tiny_scene(f"w{i}").save(tmp_path / "sc" / f"w{i}.npz")
        rows.append({"scene": f"sc/w{i}.npz", "output": f"o/w{i}.png", "backend": FAKE})
    path = tmp_path / "jobs.jsonl"
    path.write_text("\n".join(json.dumps(r) for r in rows) + "\n")
    assert main(["batch", str(path), "--executor", "ray", "--workers", "2", "--no-progress"]) == 0
    assert "3 jobs: 3 done, 0 skipped, 0 failed" in capsys.readouterr().out
    assert all((tmp_path / "o" / f"w{i}.png").is_file() for i in range(3))
