"""Choosing a Mitsuba variant without ever crashing the user's process.

The vectorised ``llvm_*`` variants JIT-compile through the system's libLLVM; with an unsuitable one
(Debian 12's LLVM 15, for instance) Dr.Jit *aborts the whole process* at the first compilation. So an
LLVM (or CUDA) variant is first tried in a subprocess that renders a tiny scene; only when that probe
exits cleanly is the variant used here, with ``DRJIT_LIBLLVM_PATH`` pointing at the library that passed.
Otherwise the backend falls back to ``scalar_rgb`` (always available) and says why in one WARNING line;
the probes' output (Dr.Jit messages, LLVM traces) is logged at DEBUG only.

Probe results are cached on disk (:func:`probe_cache_path`, JSON) per Mitsuba/Dr.Jit version, variant
and libLLVM (path, mtime, size), so only the first process on a machine pays for the probes. A probe that
timed out, could not start or was killed from outside is not cached. ``BLENDIFY_MITSUBA_PROBE_CACHE``
relocates the file (a path) or switches the cache off (``off``, ``0``, ``false``, ``none``).

Dr.Jit reads ``DRJIT_LIBLLVM_PATH`` when it is first imported, so the library is chosen before the first
``import mitsuba`` of the process. Nothing in this module imports mitsuba or drjit.
"""

from __future__ import annotations

import contextlib
import glob
import json
import logging
import os
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

log = logging.getLogger("blendify_mitsuba")

__all__ = [
    "VariantChoice",
    "ProbeAttempt",
    "choose_variant",
    "probe_variant",
    "run_probe",
    "libllvm_candidates",
    "probe_cache_path",
    "describe",
    "gpu_devices",
    "KNOWN_VARIANTS",
    "VARIANT_ENV",
    "variant_from_environment",
    "with_source",
]

SCALAR = "scalar_rgb"
#: the variants the translator supports (RGB: colours, textures and lights are given as linear RGB;
#: spectral variants refuse raw RGB bitmaps)
KNOWN_VARIANTS = ("scalar_rgb", "llvm_ad_rgb", "llvm_rgb", "cuda_ad_rgb", "cuda_rgb")
#: seconds a probe subprocess may take (first JIT compilation included)
PROBE_TIMEOUT = 120.0
#: the oldest libLLVM major version the llvm variants of Mitsuba 3.9 / Dr.Jit 1.5 are expected to work
#: with: Dr.Jit refuses 14 and older ("too old") and aborts with 15 at the first kernel (measured)
MIN_LLVM = 16
#: environment variable: a path relocates the probe cache file, off/0/false/none switches it off
CACHE_ENV = "BLENDIFY_MITSUBA_PROBE_CACHE"
#: environment variable: the variant a backend created without ``variant=`` or ``device=`` asks for (one of
#: :data:`KNOWN_VARIANTS`; unset, empty or ``auto``: the automatic choice). Lets a job script, a cluster or a
#: test run pin the variant without changing code.
VARIANT_ENV = "BLENDIFY_MITSUBA_VARIANT"
_CACHE_VERSION = 1
_CACHE_MAX_ENTRIES = 64
_DETAIL_CHARS = 2000
#: signals that come from outside the probe (OOM killer, Ctrl-C, kill): such a failure is not cached
_TRANSIENT_SIGNALS = {int(signal.SIGKILL), int(signal.SIGINT), int(signal.SIGTERM)}

_PROBE_SCRIPT = """
import sys
import mitsuba as mi
print("BLENDIFY_PROBE_IMPORTED", file=sys.stderr, flush=True)
mi.set_variant(sys.argv[1])
scene = mi.load_dict({
    "type": "scene",
    "integrator": {"type": "path", "max_depth": 3},
    "sensor": {"type": "perspective", "fov": 40,
               "film": {"type": "hdrfilm", "width": 4, "height": 4, "rfilter": {"type": "box"}}},
    "sphere": {"type": "sphere", "center": [0, 0, 4], "radius": 1.0, "bsdf": {"type": "diffuse"}},
    "light": {"type": "constant"},
})
img = mi.render(scene, spp=2)
import numpy as np
a = np.array(img)
if a.shape != (4, 4, 3) or not np.isfinite(a).all():
    raise SystemExit(f"probe render gave shape {a.shape} or non-finite values")
print("BLENDIFY_PROBE_OK")
"""


@dataclass(frozen=True)
class ProbeAttempt:
    """One probe of ``variant`` with ``libllvm`` (None: Dr.Jit's own search, or a CUDA variant).

    ``summary`` is one short line (no engine output); ``detail`` the probe's stderr tail (DEBUG only).
    ``cacheable`` is False for failures that may not happen again (timeout, killed from outside)."""

    variant: str
    libllvm: str | None
    ok: bool
    summary: str
    detail: str = ""
    llvm_version: int | None = None
    kind: str = "ok"  # ok, too_old, crashed, not_loadable, no_gpu, timeout, failed
    seconds: float = 0.0
    cacheable: bool = True
    cached: bool = False  # read from the probe cache instead of run now


@dataclass(frozen=True)
class VariantChoice:
    """The variant to use, the libLLVM it needs (or None) and why it was chosen.

    ``summary`` is the one-line cause of a fallback ("" when none), ``attempts`` every probe consulted."""

    variant: str
    libllvm: str | None
    reason: str
    summary: str = ""
    attempts: tuple[ProbeAttempt, ...] = field(default=(), compare=False)


def variant_from_environment() -> str | None:
    """The variant :data:`VARIANT_ENV` asks for (None: unset, empty or ``auto``, i.e. the automatic choice).

    Raises ``ValueError`` naming the variable and the accepted values for anything else."""
    raw = os.environ.get(VARIANT_ENV, "").strip()
    if raw in ("", "auto"):
        return None
    if raw not in KNOWN_VARIANTS:
        raise ValueError(f"{VARIANT_ENV}: expected one of {list(KNOWN_VARIANTS)} or 'auto' (or unset), got {raw!r}")
    return raw


# -- libLLVM discovery --------------------------------------------------------------------------------


def _llvm_version(path: str) -> tuple[int, ...]:
    m = re.search(r"(?:llvm-|LLVM-|\.so\.)(\d+)(?:\.(\d+))?", path)
    if not m:
        return (0,)
    return tuple(int(g) for g in m.groups() if g is not None)


def _llvm_major(path: str | None) -> int | None:
    if path is None:
        return None
    v = _llvm_version(os.path.realpath(path))[0] or _llvm_version(path)[0]
    return v or None


def libllvm_candidates() -> list[str]:
    """Installed libLLVM shared libraries, newest version first: the Python environment's own ``lib``
    folder (where the karellen-llvm-core wheel puts ``libLLVM.so.<version>``: no root needed), then the
    Debian/Ubuntu/Fedora/Homebrew layouts."""
    patterns = [
        os.path.join(glob.escape(sys.prefix), "lib", "libLLVM*.so*"),
        "/usr/lib/llvm-*/lib/libLLVM*.so*",
        "/usr/lib/x86_64-linux-gnu/libLLVM*.so*",
        "/usr/lib/aarch64-linux-gnu/libLLVM*.so*",
        "/usr/lib64/libLLVM*.so*",
        "/usr/lib/libLLVM*.so*",
        "/usr/local/lib/libLLVM*.so*",
        "/opt/homebrew/opt/llvm/lib/libLLVM.dylib",
        "/usr/local/opt/llvm/lib/libLLVM.dylib",
    ]
    found: dict[str, str] = {}
    for pat in patterns:
        for p in glob.glob(pat):
            if os.path.isfile(p):
                found.setdefault(os.path.realpath(p), p)
    paths = sorted(found, key=lambda p: _llvm_version(p), reverse=True)
    return paths


# -- the probe subprocess -----------------------------------------------------------------------------


def _one_line(text: str, limit: int = 160) -> str:
    text = " ".join(text.split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _signal_name(num: int) -> str:
    try:
        return signal.Signals(num).name
    except ValueError:
        return f"signal {num}"


def _classify(variant: str, libllvm: str | None, rc: int, stdout: str, stderr: str) -> ProbeAttempt:
    """A finished probe subprocess -> ProbeAttempt with a one-line summary (engine output kept as detail)."""
    version = _llvm_major(libllvm)
    detail = stderr.strip()[-_DETAIL_CHARS:]
    if rc == 0 and "BLENDIFY_PROBE_OK" in stdout:
        return ProbeAttempt(variant, libllvm, True, "probe passed", detail, version, "ok")
    m = re.search(r"located LLVM version \((\d+)\) is too old", stderr)
    if m:
        version = int(m.group(1))
        text = f"LLVM {version} is too old for Dr.Jit"
        return ProbeAttempt(variant, libllvm, False, text, detail, version, "too_old")
    if rc < 0:
        sig = -rc
        where = "compiling its first kernel" if "BLENDIFY_PROBE_IMPORTED" in stderr else "loading Mitsuba"
        text = f"crashed ({_signal_name(sig)}) {where}"
        if version is not None:
            text += f" with LLVM {version}"
        return ProbeAttempt(
            variant, libllvm, False, text, detail, version, "crashed", cacheable=sig not in _TRANSIENT_SIGNALS
        )
    if "Unable to load" in stderr or "LLVM API initialization failed" in stderr:
        text = "Dr.Jit could not load this libLLVM"
        return ProbeAttempt(variant, libllvm, False, text, detail, version, "not_loadable")
    if "LLVM backend is inactive" in stderr:
        return ProbeAttempt(variant, libllvm, False, "Dr.Jit found no usable libLLVM", detail, version, "not_loadable")
    tail = [t for t in stderr.strip().splitlines() if t.strip() and not t.startswith("BLENDIFY_PROBE")]
    last = _one_line(tail[-1]) if tail else "no output"
    return ProbeAttempt(variant, libllvm, False, f"probe failed (exit code {rc}): {last}", detail, version, "failed")


def run_probe(variant: str, libllvm: str | None, timeout: float = PROBE_TIMEOUT) -> ProbeAttempt:
    """Render a 4x4 image with ``variant`` in a subprocess (its output is captured, never printed)."""
    env = dict(os.environ)
    if libllvm is not None:
        env["DRJIT_LIBLLVM_PATH"] = libllvm
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(
            [sys.executable, "-c", _PROBE_SCRIPT, variant],
            env=env,
            capture_output=True,
            text=True,
            errors="replace",
            timeout=timeout,
            stdin=subprocess.DEVNULL,
        )
    except subprocess.TimeoutExpired as exc:
        err = exc.stderr.decode(errors="replace") if isinstance(exc.stderr, bytes) else (exc.stderr or "")
        return ProbeAttempt(
            variant,
            libllvm,
            False,
            f"the probe timed out after {timeout:.0f} s",
            err.strip()[-_DETAIL_CHARS:],
            _llvm_major(libllvm),
            "timeout",
            time.perf_counter() - t0,
            cacheable=False,
        )
    except OSError as exc:
        return ProbeAttempt(
            variant, libllvm, False, f"cannot start a probe subprocess ({exc})", kind="failed", cacheable=False
        )
    attempt = _classify(variant, libllvm, proc.returncode, proc.stdout or "", proc.stderr or "")
    return replace(attempt, seconds=time.perf_counter() - t0)


def probe_variant(variant: str, libllvm: str | None, timeout: float = PROBE_TIMEOUT) -> tuple[bool, str]:
    """Render a 4x4 image with ``variant`` in a subprocess (no cache). Returns (ok, one-line message)."""
    a = run_probe(variant, libllvm, timeout)
    return a.ok, a.summary


# -- the on-disk probe cache --------------------------------------------------------------------------


def probe_cache_path() -> Path | None:
    """The probe cache file, or None when ``BLENDIFY_MITSUBA_PROBE_CACHE`` switches it off.

    Default: ``$XDG_CACHE_HOME/blendify-core/mitsuba-variant-probes.json`` (``~/.cache/...``)."""
    env = os.environ.get(CACHE_ENV, "").strip()
    if env.lower() in ("off", "0", "false", "no", "none"):
        return None
    if env:
        return Path(env).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "blendify-core" / "mitsuba-variant-probes.json"


def _versions() -> str:
    from importlib import metadata

    out = []
    for dist in ("mitsuba", "drjit"):
        try:
            out.append(f"{dist}={metadata.version(dist)}")
        except metadata.PackageNotFoundError:
            out.append(f"{dist}=?")
    return ",".join(out)


def _file_id(path: str) -> str:
    real = os.path.realpath(path)
    try:
        st = os.stat(real)
    except OSError:
        return f"{path}->{real}:missing"
    return f"{path}->{real}:{st.st_mtime_ns}:{st.st_size}"


def cache_key(variant: str, libllvm: str | None) -> str | None:
    """The probe cache key: Mitsuba/Dr.Jit versions, variant and the library the probe loads (path,
    mtime, size; for Dr.Jit's own search every installed libLLVM; for CUDA the driver version).
    None when nothing identifies the library (the probe then always runs)."""
    if variant.startswith("cuda"):
        try:
            with open("/proc/driver/nvidia/version", encoding="utf-8", errors="replace") as f:
                lib = "cuda:" + _one_line(f.readline(), 200)
        except OSError:
            return None
    elif libllvm is not None:
        lib = _file_id(libllvm)
    else:
        lib = "default:" + ";".join(_file_id(p) for p in libllvm_candidates())
    return f"{_versions()}|{sys.platform}|{variant}|{lib}"


def _cache_read(path: Path) -> dict[str, Any]:
    """The cache's entries, or {} for a missing, unreadable, corrupt or foreign file."""
    try:
        with open(path, encoding="utf-8") as f:
            data = json.load(f)
    except (OSError, ValueError, UnicodeDecodeError) as exc:
        if not isinstance(exc, FileNotFoundError):
            log.debug("blendify-mitsuba: ignoring the probe cache %s (%s)", path, exc)
        return {}
    if not isinstance(data, dict) or data.get("version") != _CACHE_VERSION or not isinstance(data.get("entries"), dict):
        log.debug("blendify-mitsuba: ignoring the probe cache %s (unknown layout)", path)
        return {}
    return data["entries"]


def _from_record(variant: str, libllvm: str | None, rec: Any) -> ProbeAttempt | None:
    if not isinstance(rec, dict):
        return None
    ok, summary, detail, kind = rec.get("ok"), rec.get("summary"), rec.get("detail", ""), rec.get("kind", "failed")
    version, seconds = rec.get("llvm_version"), rec.get("seconds", 0.0)
    if not (isinstance(ok, bool) and isinstance(summary, str) and isinstance(detail, str) and isinstance(kind, str)):
        return None
    if version is not None and not isinstance(version, int):
        return None
    if not isinstance(seconds, (int, float)):
        return None
    return ProbeAttempt(variant, libllvm, ok, summary, detail, version, kind, float(seconds), True, cached=True)


def _cache_write(path: Path, key: str, attempt: ProbeAttempt) -> None:
    """Add one result; written atomically (temporary file + rename). Failures are logged at DEBUG."""
    try:
        entries = _cache_read(path)
        entries[key] = {
            "ok": attempt.ok,
            "summary": attempt.summary,
            "detail": attempt.detail,
            "kind": attempt.kind,
            "llvm_version": attempt.llvm_version,
            "seconds": round(attempt.seconds, 3),
            "time": time.time(),
        }
        if len(entries) > _CACHE_MAX_ENTRIES:  # drop the oldest

            def age(kv: tuple[str, Any]) -> float:
                t = kv[1].get("time") if isinstance(kv[1], dict) else None
                return float(t) if isinstance(t, (int, float)) else 0.0

            entries = dict(sorted(entries.items(), key=age)[-_CACHE_MAX_ENTRIES:])
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=path.name + ".", suffix=".tmp", dir=path.parent)
        try:
            with os.fdopen(fd, "w", encoding="utf-8") as f:
                json.dump({"version": _CACHE_VERSION, "entries": entries}, f, indent=1)
            os.replace(tmp, path)
        except BaseException:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
            raise
    except (OSError, TypeError, ValueError) as exc:
        log.debug("blendify-mitsuba: cannot write the probe cache %s (%s)", path, exc)


def cached_probe(variant: str, libllvm: str | None) -> ProbeAttempt:
    """:func:`run_probe` through the on-disk cache."""
    path = probe_cache_path()
    key = cache_key(variant, libllvm) if path is not None else None
    if path is not None and key is not None:
        hit = _from_record(variant, libllvm, _cache_read(path).get(key))
        if hit is not None:
            return hit
    attempt = run_probe(variant, libllvm)
    if path is not None and key is not None and attempt.cacheable:
        _cache_write(path, key, attempt)
    return attempt


# -- the choice ---------------------------------------------------------------------------------------


def gpu_devices() -> list[str]:
    """The NVIDIA GPUs here (their device nodes; the CUDA variants need one). The one place GPUs are
    enumerated: the variant choice, ``device_choice`` and ``blendify info`` call it through this module,
    so a test can replace it with a faked list."""
    if not os.path.exists("/dev/nvidiactl"):
        return []
    return sorted(glob.glob("/dev/nvidia[0-9]*"))


def _gpu_present() -> bool:
    return bool(gpu_devices())


_memo: dict[tuple[str | None, str | None], VariantChoice] = {}
_lock = threading.Lock()


_UNKNOWN = object()
#: DRJIT_LIBLLVM_PATH as it was when this backend first imported drjit (_UNKNOWN: not imported by us)
_loaded_with: object = _UNKNOWN


def _drjit_loaded() -> bool:
    return "drjit" in sys.modules


def before_engine_import() -> None:
    """Call right before importing mitsuba: remembers which libLLVM Dr.Jit is about to load."""
    global _loaded_with
    if not _drjit_loaded() and _loaded_with is _UNKNOWN:
        _loaded_with = os.environ.get("DRJIT_LIBLLVM_PATH")


_DRJIT_LINE = re.compile(r"^(jitc?_[a-z_]+\(\)|\s*$)")


@contextlib.contextmanager
def quiet_engine_import(variant: str) -> Iterator[None]:
    """Wrap the process's first ``import mitsuba`` for a scalar variant: Dr.Jit prints its LLVM start-up
    messages ("the located LLVM version (14) is too old ...") on the C-level stderr when it is imported;
    those lines go to the DEBUG log instead, any other output of the import is passed on to stderr.
    (Other threads' stderr output during the import is delayed until it finishes, not lost.)"""
    if _drjit_loaded() or not variant.startswith("scalar") or os.name != "posix":
        yield
        return
    try:
        sys.stderr.flush()
        saved = os.dup(2)
        tmp = tempfile.TemporaryFile()
        os.dup2(tmp.fileno(), 2)
    except (OSError, ValueError, AttributeError):  # no usable fd 2: import as is
        yield
        return
    try:
        yield
    finally:
        with contextlib.suppress(OSError, ValueError, AttributeError):
            sys.stderr.flush()
        os.dup2(saved, 2)
        os.close(saved)
        tmp.seek(0)
        text = tmp.read().decode(errors="replace")
        tmp.close()
        engine = [t for t in text.splitlines() if t.strip() and _DRJIT_LINE.match(t)]
        other = [t for t in text.splitlines(keepends=True) if not _DRJIT_LINE.match(t)]
        if engine:
            log.debug("blendify-mitsuba: Dr.Jit at import (scalar variant, LLVM unused): %s", " | ".join(engine))
        if other:
            with contextlib.suppress(OSError, ValueError):
                sys.stderr.write("".join(other))
                sys.stderr.flush()


def choose_variant(requested: str | None, *, quiet: bool = False) -> VariantChoice:
    """Resolve ``requested`` (None = the fastest variant that works here; "cpu" = the fastest CPU variant;
    "gpu" = cuda_ad_rgb, else as None; or a variant name) into a usable variant.

    Never raises for an unusable JIT variant: it falls back to ``scalar_rgb`` with the reason, logged as
    one WARNING line (at INFO with ``quiet``) the first time in the process; probe output at DEBUG."""
    user_llvm = os.environ.get("DRJIT_LIBLLVM_PATH")
    key = (requested, user_llvm)
    with _lock:
        if key in _memo:
            return _memo[key]
        choice = _choose(requested, user_llvm)
        _memo[key] = choice
        env_now = os.environ.get("DRJIT_LIBLLVM_PATH")
        if env_now != user_llvm:  # we chose the library: later calls see it in the environment
            _memo[(requested, env_now)] = choice
    for a in choice.attempts:
        how = "cached" if a.cached else f"probed in {a.seconds:.1f} s"
        log.debug(
            "blendify-mitsuba: probe %s with %s: %s (%s)%s",
            a.variant,
            a.libllvm or "the default library",
            a.summary,
            how,
            f"\n{a.detail}" if a.detail else "",
        )
    if choice.summary:
        log.log(
            logging.INFO if quiet else logging.WARNING,
            "blendify-mitsuba: %s; using %s; `blendify info` for details",
            choice.summary,
            choice.variant,
        )
    else:
        log.info("blendify-mitsuba: variant %s (%s)", choice.variant, choice.reason)
    return choice


def _fallback_summary(attempts: list[ProbeAttempt], wanted: list[str], no_lib: bool) -> str:
    """One line: why each wanted JIT variant is unavailable (no engine output)."""
    parts = []
    for variant in wanted:
        mine = [a for a in attempts if a.variant == variant]
        if variant.startswith("cuda"):
            if any(a.kind == "no_gpu" for a in mine) and len(wanted) > 1:
                continue  # no GPU is the normal case when the variant was not asked for by name
            cause = "; ".join(a.summary for a in mine) or "not probed"
        elif not mine and no_lib:
            cause = f"no libLLVM found (needs libLLVM >= {MIN_LLVM})"
        elif mine and all(
            a.llvm_version is not None and (a.kind == "too_old" or (a.kind == "crashed" and a.llvm_version < MIN_LLVM))
            for a in mine
        ):
            found = ", ".join(str(v) for v in sorted({a.llvm_version for a in mine if a.llvm_version}, reverse=True))
            cause = f"needs libLLVM >= {MIN_LLVM}, found {found}"
        else:
            bits = []
            for a in mine:
                lib = f"DRJIT_LIBLLVM_PATH={a.libllvm}" if a.libllvm else "the default libLLVM"
                bits.append(f"{a.summary} ({lib})")
            cause = "; ".join(bits) or "not probed"
        parts.append(f"{variant} unavailable: {_one_line(cause, 300)}")
    return "; ".join(parts) or "no JIT variant available"


def _choose(requested: str | None, user_llvm: str | None) -> VariantChoice:
    if requested is not None and requested.startswith("scalar"):
        return VariantChoice(requested, None, "requested")
    reasons: list[str] = []
    attempts: list[ProbeAttempt] = []
    no_lib = False
    if requested == "cpu":  # device="cpu": the fastest CPU variant
        wanted = ["llvm_ad_rgb"]
    elif requested == "gpu":  # device="gpu": CUDA, else the fastest CPU variant (the caller says why)
        wanted = ["cuda_ad_rgb", "llvm_ad_rgb"]
    else:
        wanted = [requested] if requested is not None else ["cuda_ad_rgb", "llvm_ad_rgb"]
    for variant in wanted:
        if variant.startswith("cuda"):
            if not _gpu_present():
                attempts.append(ProbeAttempt(variant, None, False, "no NVIDIA GPU on this machine", kind="no_gpu"))
                reasons.append(f"{variant}: no NVIDIA GPU on this machine")
                continue
            a = cached_probe(variant, None)
            attempts.append(a)
            if a.ok:
                return VariantChoice(variant, None, "CUDA probe passed", "", tuple(attempts))
            reasons.append(f"{variant}: {a.summary}")
            continue
        # LLVM variants
        if user_llvm is not None or _drjit_loaded():
            # the library is fixed: the user chose it, or Dr.Jit is already loaded in this process (then
            # with the library named by DRJIT_LIBLLVM_PATH at the time it was imported)
            lib = user_llvm
            if _drjit_loaded() and _loaded_with is not _UNKNOWN:
                lib = _loaded_with  # type: ignore[assignment]
            a = cached_probe(variant, lib)
            attempts.append(a)
            where = f"DRJIT_LIBLLVM_PATH={lib}" if lib else "Dr.Jit's default libLLVM search"
            if a.ok:
                return VariantChoice(variant, lib, f"probe passed with {where}", "", tuple(attempts))
            reasons.append(f"{variant} with {where}: {a.summary}")
            continue
        candidates = libllvm_candidates()
        if not candidates:
            no_lib = True
            reasons.append(
                f"{variant}: no libLLVM shared library found (pip install karellen-llvm-core, or Debian's libllvm19)"
            )
        for lib in candidates[:3]:
            a = cached_probe(variant, lib)
            attempts.append(a)
            if a.ok:
                os.environ["DRJIT_LIBLLVM_PATH"] = lib  # read by Dr.Jit at its first import
                return VariantChoice(variant, lib, f"probe passed with DRJIT_LIBLLVM_PATH={lib}", "", tuple(attempts))
            reasons.append(f"{variant} with {lib}: {a.summary}")
    reason = "fell back to scalar_rgb: " + "; ".join(reasons)
    return VariantChoice(SCALAR, None, reason, _fallback_summary(attempts, wanted, no_lib), tuple(attempts))


def with_source(choice: VariantChoice, source: str | None) -> VariantChoice:
    """``choice`` with its reason naming where the request came from (e.g. ``BLENDIFY_MITSUBA_VARIANT=...``)."""
    if source is None:
        return choice
    reason = f"requested by {source}" if choice.reason == "requested" else f"{choice.reason}; asked for by {source}"
    return replace(choice, reason=reason)


def describe(requested: str | None = None, source: str | None = None) -> list[str]:
    """Lines for ``blendify info``: the variant chosen for ``requested`` (asked for by ``source``, if given)
    here and why, one line per probe (runs the probes when the cache has no result for them)."""
    t0 = time.perf_counter()
    choice = with_source(choose_variant(requested, quiet=True), source)
    dt = time.perf_counter() - t0
    lines = [f"variant {choice.variant}" + (f" ({choice.summary})" if choice.summary else f" ({choice.reason})")]
    for a in choice.attempts:
        lib = a.libllvm or ("Dr.Jit's default libLLVM" if a.variant.startswith("llvm") else "")
        ver = f" (LLVM {a.llvm_version})" if a.llvm_version and f"LLVM {a.llvm_version}" not in a.summary else ""
        how = "" if a.kind == "no_gpu" else (" [cached]" if a.cached else f" [probed now, {a.seconds:.1f} s]")
        lines.append(f"  {a.variant}{' with ' + lib if lib else ''}{ver}: {a.summary}{how}")
    if choice.variant.startswith("scalar") and requested is None:
        lines.append(
            f"  for the llvm variants install libLLVM >= {MIN_LLVM} (pip install karellen-llvm-core, no root; "
            "Debian/Ubuntu: apt-get install libllvm19) or point DRJIT_LIBLLVM_PATH at one"
        )
    path = probe_cache_path()
    where = str(path) if path is not None else "off"
    lines.append(f"  probe cache: {where} (set {CACHE_ENV}=off to disable, or a file path); took {dt:.1f} s")
    return lines


_PLUGINS_REGISTERED: set[tuple[str, str]] = set()


def register_plugin(kind: str, name: str, make_class: Callable[[], type]) -> str:
    """Register blendify's Python plugin ``name`` (``kind``: ``"bsdf"`` or ``"integrator"``) for the current
    Mitsuba variant, once per variant (``make_class`` builds its class with that variant's types); its name."""
    import mitsuba as mi

    key = (mi.variant(), name)
    if key not in _PLUGINS_REGISTERED:
        cls = make_class()
        getattr(mi, f"register_{kind}")(name, lambda props: cls(props))
        _PLUGINS_REGISTERED.add(key)
    return name
