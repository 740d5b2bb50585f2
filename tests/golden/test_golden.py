"""Golden images: small reference renders per backend and scene, compared with named tolerances.

References live in ``tests/golden/<engine>/<case>.png`` (8-bit sRGB, straight alpha, <= 128 px) and are
regenerated only on purpose: ``pytest tests/golden --update-golden``. On a mismatch the actual, expected
and diff images are written to ``artifacts/golden/<engine>/`` so the failure can be looked at.

Mitsuba has one set of references per variant (``mitsuba_scalar_rgb``, ``mitsuba_llvm_ad_rgb``): the variants
draw different random sequences, so at a golden's sample count their images differ by more than the
tolerances. ``scalar_rgb`` is always tested; ``llvm_ad_rgb`` where its libLLVM is usable (skipped with the
reason otherwise), so the outcome never depends on which variant the machine happens to pick.

Path tracers render with a fixed seed, a box filter and no denoiser, which is deterministic on one
machine; the tolerances absorb what may differ between CPUs and library builds (a few 8-bit levels on
noisy pixels), not real changes: a moved object, a wrong colour space or a flipped texture fail.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import blendify_core as bf
from blendify_core import testing as T
from blendify_core.registry import shared_backend

HERE = Path(__file__).resolve().parent
ARTIFACTS = HERE.parents[1] / "artifacts" / "golden"
#: golden engine name -> (backend, backend options)
ENGINES: dict[str, tuple[str, dict[str, str]]] = {
    "cycles": ("cycles", {}),
    "mitsuba_scalar_rgb": ("mitsuba", {"variant": "scalar_rgb"}),
    "mitsuba_llvm_ad_rgb": ("mitsuba", {"variant": "llvm_ad_rgb"}),
    "pyrender": ("pyrender", {}),
}
SAMPLES = 16

CASES = {
    "markers": lambda: T.marker_scene(resolution=(96, 72), fx=90.0, center=(50.3, 33.1), radius=0.35)[0],
    "plane_point": lambda: T.plane_scene("point", resolution=(48, 48)),
    "textured_quad": lambda: T.textured_quad_scene(resolution=(48, 48)),
    "primitives": lambda: T.primitives_scene(resolution=(96, 72)),
    "pointcloud": lambda: T.pointcloud_scene(n=400, resolution=(64, 64), point_size=0.08),
    "bunny": lambda: T.bunny_scene(resolution=(64, 64)),
}

#: named tolerances on 8-bit sRGB values (RGB of pixels covered in both, and alpha everywhere)
TOLERANCE = {
    "mean_abs": 1.5,  # mean absolute difference, levels
    "q99_abs": 24.0,  # 99th percentile, levels (noisy single pixels)
    "alpha_mean_abs": 2.0,  # mean absolute alpha difference, levels
}


def _status(engine: str) -> str | None:
    name, options = ENGINES[engine]
    st = bf.available_backends().get(name)
    if st is None:
        return f"backend {name!r} is not registered"
    if not st.available:
        return f"backend {name!r} unavailable: {st.reason}"
    wanted = options.get("variant")
    if wanted is not None:
        choice = shared_backend(name, **options).variant_choice
        if choice.variant != wanted:
            return f"Mitsuba variant {wanted} unavailable here: {choice.reason}"
    return None


def _render(engine: str, case: str) -> np.ndarray:
    name, options = ENGINES[engine]
    result = bf.render(CASES[case](), backend=name, samples=SAMPLES, seed=0, quality="final", denoise=False, **options)
    if "variant" in options:
        assert result.meta["variant"] == options["variant"], f"rendered with {result.meta['variant']}"
    return result.to_srgb8()


def _load(path: Path) -> np.ndarray:
    from PIL import Image

    with Image.open(path) as im:
        return np.asarray(im.convert("RGBA"))


def _save(path: Path, image: np.ndarray) -> None:
    from PIL import Image

    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(image).save(path, optimize=True)


def compare_images(actual: np.ndarray, expected: np.ndarray) -> dict[str, float]:
    """Differences between two RGBA uint8 images (the metrics the tolerances name)."""
    a = actual.astype(np.float64)
    e = expected.astype(np.float64)
    both = (actual[..., 3] > 0) & (expected[..., 3] > 0)
    rgb = np.abs(a[..., :3] - e[..., :3])[both]
    return {
        "mean_abs": float(rgb.mean()) if rgb.size else 0.0,
        "q99_abs": float(np.quantile(rgb, 0.99)) if rgb.size else 0.0,
        "alpha_mean_abs": float(np.abs(a[..., 3] - e[..., 3]).mean()),
    }


def _write_failure(backend: str, case: str, actual: np.ndarray, expected: np.ndarray) -> Path:
    out = ARTIFACTS / backend
    diff = np.abs(actual.astype(np.int16) - expected.astype(np.int16)).max(axis=-1)
    heat = np.zeros(actual.shape[:2] + (3,), np.uint8)
    heat[..., 0] = np.clip(diff * 8, 0, 255)
    heat[..., 1] = np.clip(diff * 2, 0, 255)
    _save(out / f"{case}.actual.png", actual)
    _save(out / f"{case}.expected.png", expected)
    _save(out / f"{case}.diff.png", np.dstack([heat, np.full(actual.shape[:2], 255, np.uint8)]))
    return out


@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("backend", sorted(ENGINES))
def test_golden(backend: str, case: str, update_golden: bool) -> None:
    reason = _status(backend)
    if reason:
        print(f"SKIP: {reason}")
        pytest.skip(reason)
    actual = _render(backend, case)
    path = HERE / backend / f"{case}.png"
    if update_golden:
        _save(path, actual)
        pytest.skip(f"golden image regenerated: {path.relative_to(HERE)}")
    if not path.exists():
        pytest.fail(f"no golden image {path.relative_to(HERE)}; create it with `pytest tests/golden --update-golden`")
    expected = _load(path)
    assert actual.shape == expected.shape, f"shape {actual.shape} != golden {expected.shape}"
    metrics = compare_images(actual, expected)
    failed = {k: v for k, v in metrics.items() if v > TOLERANCE[k]}
    if failed:
        where = _write_failure(backend, case, actual, expected)
        pytest.fail(
            f"{backend}/{case} differs from its golden image: {failed} (tolerances {TOLERANCE}); "
            f"actual/expected/diff written to {where}"
        )


def test_goldens_are_small() -> None:
    for path in HERE.glob("*/*.png"):
        img = _load(path)
        assert max(img.shape[:2]) <= 128, f"{path.name} is larger than 128 px"
        assert path.stat().st_size < 64 * 1024, f"{path.name} is larger than 64 KiB"


def test_comparison_catches_real_changes() -> None:
    """The tolerances must fail a one-pixel shift of an edge, a colour-space error and a flipped texture."""
    img = np.zeros((48, 48, 4), np.uint8)
    img[10:38, 10:38] = (200, 120, 60, 255)
    shifted = np.roll(img, 1, axis=1)
    wrong_space = img.copy()
    wrong_space[10:38, 10:38, :3] = (200 * 200 // 255, 120 * 120 // 255, 60 * 60 // 255)
    flipped = img.copy()
    flipped[10:24, 10:38, :3] = (60, 120, 200)
    for bad in (shifted, wrong_space, flipped):
        metrics = compare_images(bad, img)
        assert any(metrics[k] > TOLERANCE[k] for k in TOLERANCE), metrics
    assert all(v <= TOLERANCE[k] for k, v in compare_images(img, img).items())
