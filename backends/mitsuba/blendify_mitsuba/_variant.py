"""Choosing a Mitsuba variant without ever crashing the user's process.

The vectorised ``llvm_*`` variants JIT-compile through the system's libLLVM; with an unsuitable one
(Debian 12's LLVM 15, for instance) Dr.Jit *aborts the whole process* at the first compilation. So an
LLVM (or CUDA) variant is first tried in a subprocess that renders a tiny scene; only when that probe
exits cleanly is the variant used here, with ``DRJIT_LIBLLVM_PATH`` pointing at the library that passed.
Otherwise the backend falls back to ``scalar_rgb`` (always available) and says why.

Dr.Jit reads ``DRJIT_LIBLLVM_PATH`` when it is first imported, so the library is chosen before the first
``import mitsuba`` of the process. Nothing in this module imports mitsuba or drjit.
"""

from __future__ import annotations

import glob
import logging
import os
import re
import subprocess
import sys
import threading
from dataclasses import dataclass

log = logging.getLogger("blendify_mitsuba")

__all__ = ["VariantChoice", "choose_variant", "probe_variant", "libllvm_candidates", "KNOWN_VARIANTS"]

SCALAR = "scalar_rgb"
#: the variants the translator supports (RGB: colours, textures and lights are given as linear RGB;
#: spectral variants refuse raw RGB bitmaps)
KNOWN_VARIANTS = ("scalar_rgb", "llvm_ad_rgb", "llvm_rgb", "cuda_ad_rgb", "cuda_rgb")
#: seconds a probe subprocess may take (first JIT compilation included)
PROBE_TIMEOUT = 120.0

_PROBE_SCRIPT = """
import sys
import mitsuba as mi
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
class VariantChoice:
    """The variant to use, the libLLVM it needs (or None) and why it was chosen."""

    variant: str
    libllvm: str | None
    reason: str


def _llvm_version(path: str) -> tuple[int, ...]:
    m = re.search(r"(?:llvm-|LLVM-|\.so\.)(\d+)(?:\.(\d+))?", path)
    if not m:
        return (0,)
    return tuple(int(g) for g in m.groups() if g is not None)


def libllvm_candidates() -> list[str]:
    """Installed libLLVM shared libraries, newest version first (Debian/Ubuntu/Fedora layouts)."""
    patterns = [
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


def probe_variant(variant: str, libllvm: str | None, timeout: float = PROBE_TIMEOUT) -> tuple[bool, str]:
    """Render a 4x4 image with ``variant`` in a subprocess. Returns (ok, message)."""
    env = dict(os.environ)
    if libllvm is not None:
        env["DRJIT_LIBLLVM_PATH"] = libllvm
    try:
        proc = subprocess.run(
            [sys.executable, "-c", _PROBE_SCRIPT, variant],
            env=env,
            capture_output=True,
            text=True,
            timeout=timeout,
        )
    except subprocess.TimeoutExpired:
        return False, f"the probe of {variant} timed out after {timeout:.0f} s"
    except OSError as exc:
        return False, f"cannot start a probe subprocess ({exc})"
    if proc.returncode == 0 and "BLENDIFY_PROBE_OK" in proc.stdout:
        return True, "probe passed"
    tail = (proc.stderr or proc.stdout).strip().splitlines()[-3:]
    how = f"exit code {proc.returncode}" if proc.returncode >= 0 else f"killed by signal {-proc.returncode}"
    return False, f"the probe of {variant} failed ({how}): " + " | ".join(t.strip()[:200] for t in tail)


def _gpu_present() -> bool:
    return any(os.path.exists(p) for p in ("/dev/nvidiactl", "/dev/nvidia0"))


_cache: dict[tuple[str | None, str | None], VariantChoice] = {}
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


def choose_variant(requested: str | None) -> VariantChoice:
    """Resolve ``requested`` (None = the fastest variant that works here) into a usable variant.

    Never raises for an unusable JIT variant: it falls back to ``scalar_rgb`` with the reason."""
    user_llvm = os.environ.get("DRJIT_LIBLLVM_PATH")
    key = (requested, user_llvm)
    with _lock:
        if key in _cache:
            return _cache[key]
        choice = _choose(requested, user_llvm)
        _cache[key] = choice
        env_now = os.environ.get("DRJIT_LIBLLVM_PATH")
        if env_now != user_llvm:  # we chose the library: later calls see it in the environment
            _cache[(requested, env_now)] = choice
    if choice.variant != (requested or choice.variant) or requested is None:
        log.info("blendify-mitsuba: variant %s (%s)", choice.variant, choice.reason)
    return choice


def _choose(requested: str | None, user_llvm: str | None) -> VariantChoice:
    if requested is not None and requested.startswith("scalar"):
        return VariantChoice(requested, None, "requested")
    reasons: list[str] = []
    wanted = [requested] if requested is not None else ["cuda_ad_rgb", "llvm_ad_rgb"]
    for variant in wanted:
        if variant.startswith("cuda"):
            if not _gpu_present():
                reasons.append(f"{variant}: no NVIDIA GPU on this machine")
                continue
            ok, msg = probe_variant(variant, None)
            if ok:
                return VariantChoice(variant, None, "CUDA probe passed")
            reasons.append(f"{variant}: {msg}")
            continue
        # LLVM variants
        if user_llvm is not None or _drjit_loaded():
            # the library is fixed: the user chose it, or Dr.Jit is already loaded in this process (then
            # with the library named by DRJIT_LIBLLVM_PATH at the time it was imported)
            lib = user_llvm
            if _drjit_loaded() and _loaded_with is not _UNKNOWN:
                lib = _loaded_with  # type: ignore[assignment]
            ok, msg = probe_variant(variant, lib)
            where = f"DRJIT_LIBLLVM_PATH={lib}" if lib else "Dr.Jit's default libLLVM search"
            if ok:
                return VariantChoice(variant, lib, f"probe passed with {where}")
            reasons.append(f"{variant} with {where}: {msg}")
            continue
        candidates = libllvm_candidates()
        if not candidates:
            reasons.append(f"{variant}: no libLLVM shared library found (install e.g. Debian's libllvm19)")
        for lib in candidates[:3]:
            ok, msg = probe_variant(variant, lib)
            if ok:
                os.environ["DRJIT_LIBLLVM_PATH"] = lib  # read by Dr.Jit at its first import
                return VariantChoice(variant, lib, f"probe passed with DRJIT_LIBLLVM_PATH={lib}")
            reasons.append(f"{variant} with {lib}: {msg}")
    reason = "fell back to scalar_rgb: " + "; ".join(reasons)
    log.warning("blendify-mitsuba: %s", reason)
    return VariantChoice(SCALAR, None, reason)
