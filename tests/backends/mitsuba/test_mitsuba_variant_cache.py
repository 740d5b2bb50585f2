"""The variant probe's disk cache and its messages: later processes skip the probe subprocesses, a broken
cache never breaks the backend, a changed libLLVM is probed again, and a fallback is one WARNING line
with the engine's output at DEBUG only.

The probe subprocess is replaced by a fake here (except in the last test, which runs a real child)."""

from __future__ import annotations

import json
import logging
import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import pytest
from blendify_mitsuba import variant as _variant

LLVM_TRACE = (
    "0x56095a451ec0: i64 = TargetConstantPool<float 0x3FEE666660000000> 0\n"
    "  0x56095a433028: i64 = undef\nIn function: drjit_cbaff0b7f943b150f992963bd9968b06"
)


class FakeProbe:
    """Stands in for run_probe: counts the calls, answers from ``results`` (variant, lib) -> attempt."""

    def __init__(self, results=None, default=None):
        self.calls: list[tuple[str, str | None]] = []
        self.results = results or {}
        self.default = default

    def __call__(self, variant, libllvm, timeout=_variant.PROBE_TIMEOUT):
        self.calls.append((variant, libllvm))
        a = self.results.get((variant, libllvm), self.default)
        if a is None:  # an LLVM 15 abort, as on Debian 12
            a = _variant._classify(variant, libllvm, -6, "", "BLENDIFY_PROBE_IMPORTED\n" + LLVM_TRACE)
        return replace(a, variant=variant, libllvm=libllvm)


@pytest.fixture
def env(tmp_path, monkeypatch):
    """A private cache file, a fake libLLVM 15 file, no GPU, Dr.Jit not loaded, nothing memoised, the
    automatic choice (no $BLENDIFY_MITSUBA_VARIANT)."""
    cache = tmp_path / "cache" / "probes.json"
    lib = tmp_path / "lib" / "libLLVM-15.so.1"
    lib.parent.mkdir()
    lib.write_bytes(b"not really a library")
    monkeypatch.setenv(_variant.CACHE_ENV, str(cache))
    monkeypatch.delenv("DRJIT_LIBLLVM_PATH", raising=False)
    monkeypatch.delenv(_variant.VARIANT_ENV, raising=False)
    monkeypatch.setattr(_variant, "_memo", {})
    monkeypatch.setattr(_variant, "_gpu_present", lambda: False)
    monkeypatch.setattr(_variant, "_drjit_loaded", lambda: False)
    monkeypatch.setattr(_variant, "libllvm_candidates", lambda: [str(lib)])
    fake = FakeProbe()
    monkeypatch.setattr(_variant, "run_probe", fake)
    return {"cache": cache, "lib": lib, "fake": fake, "monkeypatch": monkeypatch}


def _fresh_process(monkeypatch):
    """What a new process sees: nothing memoised in memory."""
    monkeypatch.setattr(_variant, "_memo", {})


def test_cache_hit_skips_the_probe_subprocess(env):
    fake, lib = env["fake"], str(env["lib"])
    first = _variant.choose_variant(None)
    assert first.variant == "scalar_rgb" and fake.calls == [("llvm_ad_rgb", lib)]
    assert env["cache"].is_file()
    assert not first.attempts[-1].cached
    _fresh_process(env["monkeypatch"])
    second = _variant.choose_variant(None)
    assert fake.calls == [("llvm_ad_rgb", lib)]  # no second probe
    assert second.variant == "scalar_rgb" and second.reason == first.reason
    assert second.attempts[-1].cached and second.attempts[-1].kind == "crashed"
    assert second.attempts[-1].detail.endswith("drjit_cbaff0b7f943b150f992963bd9968b06")


def test_a_passing_probe_is_cached_too(env):
    ok = _variant.ProbeAttempt("llvm_ad_rgb", None, True, "probe passed", kind="ok")
    env["fake"].default = ok
    assert _variant.cached_probe("llvm_ad_rgb", str(env["lib"])).ok
    again = _variant.cached_probe("llvm_ad_rgb", str(env["lib"]))
    assert again.ok and again.cached and len(env["fake"].calls) == 1


@pytest.mark.parametrize(
    "content",
    [
        b"{ this is not json",
        b"\xff\xfe\x00garbage",
        b"[1, 2, 3]",
        json.dumps({"version": 999, "entries": {}}).encode(),
        b"",
    ],
    ids=["syntax", "binary", "list", "other-version", "empty"],
)
def test_corrupt_cache_file_is_ignored_and_replaced(env, content):
    env["cache"].parent.mkdir(parents=True)
    env["cache"].write_bytes(content)
    choice = _variant.choose_variant(None)
    assert choice.variant == "scalar_rgb" and len(env["fake"].calls) == 1
    data = json.loads(env["cache"].read_text())  # rewritten as a valid cache
    assert data["version"] == 1 and len(data["entries"]) == 1


def test_corrupt_entry_is_ignored(env):
    key = _variant.cache_key("llvm_ad_rgb", str(env["lib"]))
    env["cache"].parent.mkdir(parents=True)
    env["cache"].write_text(json.dumps({"version": 1, "entries": {key: {"ok": "yes", "summary": 3}}}))
    a = _variant.cached_probe("llvm_ad_rgb", str(env["lib"]))
    assert not a.cached and len(env["fake"].calls) == 1


def test_unwritable_cache_location_just_probes(env):
    blocker = env["cache"].parent.parent / "a-file"
    blocker.write_text("x")
    env["monkeypatch"].setenv(_variant.CACHE_ENV, str(blocker / "sub" / "probes.json"))  # parent is a file
    for _ in range(2):
        _fresh_process(env["monkeypatch"])
        assert _variant.choose_variant(None).variant == "scalar_rgb"
    assert len(env["fake"].calls) == 2  # probed each time, never crashed


def test_cache_can_be_switched_off(env):
    env["monkeypatch"].setenv(_variant.CACHE_ENV, "off")
    assert _variant.probe_cache_path() is None
    _variant.cached_probe("llvm_ad_rgb", str(env["lib"]))
    _variant.cached_probe("llvm_ad_rgb", str(env["lib"]))
    assert len(env["fake"].calls) == 2 and not env["cache"].exists()


def test_default_cache_location_follows_xdg(monkeypatch, tmp_path):
    monkeypatch.delenv(_variant.CACHE_ENV, raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert _variant.probe_cache_path() == tmp_path / "blendify-core" / "mitsuba-variant-probes.json"


def test_cache_key_changes_when_the_library_changes(env):
    lib = env["lib"]
    k1 = _variant.cache_key("llvm_ad_rgb", str(lib))
    st = lib.stat()
    os.utime(lib, ns=(st.st_atime_ns, st.st_mtime_ns + 5_000_000_000))  # e.g. the package was upgraded
    k2 = _variant.cache_key("llvm_ad_rgb", str(lib))
    assert k1 != k2
    assert _variant.cache_key("llvm_rgb", str(lib)) != k2  # per variant
    _variant.cached_probe("llvm_ad_rgb", str(lib))
    _variant.cached_probe("llvm_ad_rgb", str(lib))
    assert len(env["fake"].calls) == 1
    lib.write_bytes(b"a different library, another size")
    _variant.cached_probe("llvm_ad_rgb", str(lib))
    assert len(env["fake"].calls) == 2  # probed again


def test_timeouts_are_not_cached(env):
    env["fake"].default = _variant.ProbeAttempt(
        "llvm_ad_rgb", None, False, "the probe timed out after 120 s", kind="timeout", cacheable=False
    )
    _variant.cached_probe("llvm_ad_rgb", str(env["lib"]))
    _variant.cached_probe("llvm_ad_rgb", str(env["lib"]))
    assert len(env["fake"].calls) == 2


def test_probe_outcomes_are_classified():
    a = _variant._classify("llvm_ad_rgb", "/x/libLLVM-15.so.1", -6, "", "BLENDIFY_PROBE_IMPORTED\n" + LLVM_TRACE)
    assert a.kind == "crashed" and a.llvm_version == 15 and a.cacheable and "SIGABRT" in a.summary
    assert "TargetConstantPool" not in a.summary and "TargetConstantPool" in a.detail
    killed = _variant._classify("llvm_ad_rgb", "/x/libLLVM-19.so.1", -9, "", "BLENDIFY_PROBE_IMPORTED\n")
    assert killed.kind == "crashed" and not killed.cacheable  # SIGKILL (OOM killer, kill): may pass next time
    old = _variant._classify(
        "llvm_ad_rgb",
        "/x/libLLVM-14.so.1",
        1,
        "",
        "jit_llvm_init(): the located LLVM version (14) is too old. The Dr.Jit LLVM backend requires LLVM 15\n"
        "ImportError: jit_init_thread_state(): the LLVM backend is inactive",
    )
    assert old.kind == "too_old" and old.llvm_version == 14
    ok = _variant._classify("llvm_ad_rgb", None, 0, "BLENDIFY_PROBE_OK\n", "")
    assert ok.ok and ok.kind == "ok"


def test_fallback_is_one_warning_line_details_at_debug(env, caplog):
    lib14 = env["lib"].parent / "libLLVM-14.so.1"
    lib14.write_bytes(b"x")
    env["monkeypatch"].setattr(_variant, "libllvm_candidates", lambda: [str(env["lib"]), str(lib14)])
    env["fake"].results[("llvm_ad_rgb", str(lib14))] = _variant._classify(
        "llvm_ad_rgb", str(lib14), 1, "", "jit_llvm_init(): the located LLVM version (14) is too old.\n"
    )
    with caplog.at_level(logging.DEBUG, logger="blendify_mitsuba"):
        choice = _variant.choose_variant(None)
        _variant.choose_variant(None)  # once per process
    assert choice.variant == "scalar_rgb"
    warnings = [r for r in caplog.records if r.levelno >= logging.WARNING]
    assert len(warnings) == 1 and warnings[0].levelno == logging.WARNING
    msg = warnings[0].getMessage()
    assert "\n" not in msg
    assert msg == (
        "blendify-mitsuba: llvm_ad_rgb unavailable: needs libLLVM >= 16, found 15, 14; using scalar_rgb; "
        "`blendify info` for details"
    )
    debug = "\n".join(r.getMessage() for r in caplog.records if r.levelno == logging.DEBUG)
    assert "TargetConstantPool" in debug and "too old" in debug  # the engine output, at DEBUG only
    assert "TargetConstantPool" not in choice.reason  # meta["variant_reason"] stays free of traces
    assert str(env["lib"]) in choice.reason and str(lib14) in choice.reason


def test_no_library_and_user_library_summaries(env, caplog):
    env["monkeypatch"].setattr(_variant, "libllvm_candidates", lambda: [])
    with caplog.at_level(logging.WARNING, logger="blendify_mitsuba"):
        choice = _variant.choose_variant("llvm_ad_rgb")
    assert choice.summary == "llvm_ad_rgb unavailable: no libLLVM found (needs libLLVM >= 16)"
    assert env["fake"].calls == [] and len(caplog.records) == 1
    _fresh_process(env["monkeypatch"])
    env["monkeypatch"].setenv("DRJIT_LIBLLVM_PATH", "/nonexistent/libLLVM.so")
    env["fake"].default = _variant._classify(
        "llvm_ad_rgb", None, 1, "", 'jit_find_library(): Unable to load "/nonexistent/libLLVM.so"\n'
    )
    choice = _variant.choose_variant("llvm_ad_rgb")
    assert choice.summary == (
        "llvm_ad_rgb unavailable: Dr.Jit could not load this libLLVM (DRJIT_LIBLLVM_PATH=/nonexistent/libLLVM.so)"
    )


def test_info_details_show_the_choice_and_the_probes(env):
    from blendify_mitsuba import MitsubaBackend

    lines = MitsubaBackend.info_details()
    text = "\n".join(lines)
    assert lines[0] == "variant scalar_rgb (llvm_ad_rgb unavailable: needs libLLVM >= 16, found 15)"
    assert f"llvm_ad_rgb with {env['lib']}: crashed (SIGABRT) compiling its first kernel" in text
    assert "[probed now" in text and "cuda_ad_rgb: no NVIDIA GPU" in text
    assert str(env["cache"]) in text and "TargetConstantPool" not in text
    _fresh_process(env["monkeypatch"])
    assert "[cached]" in "\n".join(MitsubaBackend.info_details())


@pytest.mark.mitsuba
def test_child_process_stderr_is_one_line(tmp_path):
    """A real process rendering with an unusable libLLVM: its stderr is our one line, nothing from
    Dr.Jit's import (which prints "Unable to load ..." for this library) nor from the probe."""
    import importlib.util

    if importlib.util.find_spec("mitsuba") is None:
        print("mitsuba is not installed: no real child process to check")
        pytest.skip("mitsuba is not installed")
    script = (
        "import blendify_core as bf\n"
        "from blendify_core import testing\n"
        "r = bf.render(testing.plane_scene('sun', resolution=(8, 8)), backend='mitsuba', variant='llvm_ad_rgb',"
        " samples=1)\n"
        "print(r.meta['variant'])\n"
    )
    env = dict(
        os.environ,
        DRJIT_LIBLLVM_PATH="/nonexistent/libLLVM.so",
        BLENDIFY_MITSUBA_PROBE_CACHE=str(tmp_path / "probes.json"),
    )
    for run in ("cold cache", "warm cache"):
        proc = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=300)
        assert proc.returncode == 0, proc.stderr[-2000:]
        assert proc.stdout.strip() == "scalar_rgb"
        lines = proc.stderr.strip().splitlines()
        assert len(lines) == 1, f"{run}: {proc.stderr!r}"
        # the loggers have a NullHandler: the one line is bf.render's warning about the variant asked for
        assert "UserWarning: mitsuba: variant='llvm_ad_rgb' is unavailable here (llvm variants unavailable:" in lines[0]
        assert "rendering on CPU (scalar_rgb)" in lines[0] and "jit_" not in lines[0]
    assert Path(tmp_path / "probes.json").is_file()


@pytest.mark.mitsuba
def test_blendify_info_shows_the_variant(tmp_path):
    import importlib.util

    if importlib.util.find_spec("mitsuba") is None:
        print("mitsuba is not installed: `blendify info` reports it unavailable, no variant to show")
        pytest.skip("mitsuba is not installed")
    env = dict(os.environ, BLENDIFY_MITSUBA_PROBE_CACHE=str(tmp_path / "probes.json"))
    env.pop("DRJIT_LIBLLVM_PATH", None)
    env.pop("BLENDIFY_MITSUBA_VARIANT", None)  # the automatic choice, with its probes
    proc = subprocess.run(
        [sys.executable, "-m", "blendify_core", "info"], env=env, capture_output=True, text=True, timeout=600
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    lines = proc.stdout.splitlines()
    i = next(k for k, line in enumerate(lines) if line.strip().startswith("mitsuba") and "available" in line)
    assert lines[i + 1].strip().startswith("variant "), proc.stdout
    assert f"probe cache: {tmp_path / 'probes.json'}" in proc.stdout
    assert "TargetConstantPool" not in proc.stdout + proc.stderr
    assert "blendify info` for details" not in proc.stderr  # no advice to run the command being run


def test_libllvm_in_the_python_environment_is_a_candidate(tmp_path, monkeypatch):
    """A libLLVM installed by a wheel into the environment's own lib folder (karellen-llvm-core: no root
    needed) is found, newest version first."""
    (tmp_path / "lib").mkdir()
    lib = tmp_path / "lib" / "libLLVM.so.23.1"
    lib.write_bytes(b"")
    monkeypatch.setattr(_variant.sys, "prefix", str(tmp_path))
    found = _variant.libllvm_candidates()
    assert found[0] == os.path.realpath(lib)
