"""Packaging promises: one version for the four distributions, entry points, typed package, quick start."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import tomllib

import blendify_core as bf

ROOT = Path(__file__).resolve().parents[2]
MEMBERS = {"blender": "cycles", "mitsuba": "mitsuba", "pyrender": "pyrender"}


def _project(path: Path) -> dict:
    return tomllib.loads(path.read_text())["project"]


def test_one_version_for_all_distributions():
    versions = {"blendify-core": _project(ROOT / "pyproject.toml")["version"]}
    for member in MEMBERS:
        versions[f"blendify-{member}"] = _project(ROOT / "backends" / member / "pyproject.toml")["version"]
    assert set(versions.values()) == {bf.__version__}, versions


def test_backends_register_entry_points_by_name():
    for member, name in MEMBERS.items():
        eps = _project(ROOT / "backends" / member / "pyproject.toml")["entry-points"]["blendify.backends"]
        assert list(eps) == [name]
        assert eps[name].startswith(f"blendify_{member}:")
    from importlib import metadata

    installed = set()
    for member, name in MEMBERS.items():
        try:
            metadata.version(f"blendify-{member}")
            installed.add(name)
        except metadata.PackageNotFoundError:  # the core alone (CI's numpy-2 environment)
            pass
    assert installed <= set(bf.backend_names())


def test_core_ranges_admit_numpy2_and_python312():
    core = _project(ROOT / "pyproject.toml")
    numpy_req = next(d for d in core["dependencies"] if d.startswith("numpy"))
    assert "<2" not in numpy_req.replace(" ", "")
    assert not re.search(r"<\s*3\.12", core["requires-python"])


def test_typed_markers_present():
    assert (ROOT / "blendify_core" / "py.typed").is_file()
    for member in MEMBERS:
        assert (ROOT / "backends" / member / f"blendify_{member}" / "py.typed").is_file()


def test_readme_quick_start_is_two_commands_and_ci_runs_the_test_one():
    readme = (ROOT / "README.md").read_text()
    block = readme.split("## Quick start", 1)[1].split("```bash", 1)[1].split("```", 1)[0]
    commands = [line.split("#")[0].strip() for line in block.strip().splitlines() if line.strip()]
    assert len(commands) == 2, commands
    assert "blendify demo" in commands[0]
    ci = (ROOT / ".ci" / "run").read_text()
    assert f"\n{commands[1]}\n" in ci, f"CI must run the README's test command {commands[1]!r}"


def test_cli_help_and_bad_arguments():
    run = [sys.executable, "-m", "blendify_core"]
    ok = subprocess.run([*run, "--help"], capture_output=True, text=True, timeout=60)
    assert ok.returncode == 0 and "render" in ok.stdout and "demo" in ok.stdout
    for sub in ("info", "render", "demo"):
        h = subprocess.run([*run, sub, "--help"], capture_output=True, text=True, timeout=60)
        assert h.returncode == 0, sub
    bad = subprocess.run([*run, "render", "missing-scene.npz"], capture_output=True, text=True, timeout=60)
    assert bad.returncode == 2  # bad input (errors.EXIT_CODES)
    assert bad.stderr.strip().count("\n") == 0 and "no such scene file" in bad.stderr
    bad = subprocess.run([*run, "nonsense"], capture_output=True, text=True, timeout=60)
    assert bad.returncode == 2 and bad.stderr.strip().count("\n") == 0
    bad = subprocess.run([*run, "demo", "--size", "0"], capture_output=True, text=True, timeout=60)
    assert bad.returncode == 2 and "--size" in bad.stderr


def test_ci_runs_the_quick_start_in_a_fresh_clone_as_a_user():
    ci = (ROOT / ".ci" / "run").read_text()
    fresh = ci.split("apt-get", 1)[0]  # everything before the optional system packages are installed
    assert "git clone" in fresh and "mktemp -d" in fresh and "runuser" in fresh
    assert "uv run blendify demo" in fresh and "uv run pytest" in fresh


def test_nothing_reads_outside_the_repository():
    """Tests, examples, benchmarks and the library use the repository's own data (tests/data)."""
    pattern = re.compile(r"\.\./shared|parents\[\d\]\s*/\s*['\"]shared|['\"]shared['\"]\s*/\s*['\"]data")
    offenders = []
    for folder in ("blendify_core", "backends", "tests", "examples", "benchmarks"):
        for path in (ROOT / folder).rglob("*.py"):
            for n, line in enumerate(path.read_text().splitlines(), 1):
                if pattern.search(line):
                    offenders.append(f"{path.relative_to(ROOT)}:{n}: {line.strip()}")
    assert not offenders, offenders
    data = ROOT / "tests" / "data"
    assert (data / "README.md").is_file()
    for name in ("bunny.ply", "fuze.obj", "fuze.obj.mtl", "fuze uv.jpg"):
        assert (data / name).is_file() and name.split()[0] in (data / "README.md").read_text()
