"""The core type-checks: ``mypy`` with the project's [tool.mypy] configuration (what CI's `uv run mypy` runs)
finds no issue, so the typed seams (RenderMeta, Backend.translate(scene: Scene, ...), bf.render) hold."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.slow
def test_mypy_finds_no_issue_in_the_core(tmp_path):
    try:
        import mypy  # noqa: F401
    except ImportError as exc:
        reason = f"mypy is not installed ({exc}); it is in the dev group: uv sync"
        print(reason)
        pytest.skip(reason)
    res = subprocess.run(
        [sys.executable, "-m", "mypy", "--cache-dir", str(tmp_path / "mypy_cache")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert res.returncode == 0, f"mypy failed:\n{res.stdout[-6000:]}\n{res.stderr[-2000:]}"
    assert "Success: no issues found" in res.stdout


def test_the_mypy_configuration_holds_the_ir_and_the_pipeline_to_strict_flags():
    """The configuration CI's `uv run mypy` reads: every strict flag on the IR and the pipeline."""
    try:
        import tomllib
    except ImportError:  # Python 3.10
        reason = "tomllib needs Python 3.11+"
        print(reason)
        pytest.skip(reason)
    cfg = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["mypy"]
    assert cfg["packages"] == ["blendify_core"]
    strict = next(o for o in cfg["overrides"] if "blendify_core.pipeline.*" in o["module"])
    assert "blendify_core.ir.*" in strict["module"]
    for flag in ("disallow_untyped_defs", "disallow_any_generics", "warn_return_any", "disallow_untyped_calls"):
        assert strict[flag] is True, flag
    assert strict["implicit_reexport"] is False
    ci = (ROOT / ".ci" / "run").read_text()
    assert "\nuv run mypy" in ci and ci.index("uv run ruff check .") < ci.index("uv run mypy")
