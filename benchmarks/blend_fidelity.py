""".blend fidelity: third-party .blend files rendered by Blender itself and by blendify (Cycles, Mitsuba, pyrender).

The files: the committed ones in ``tests/third_party/blend/`` (``tests/third_party/SOURCES.md``: open licences)
and the cache-only ones under ``$BLENDIFY_THIRD_PARTY_DIR/blend/`` (skipped with the reason when absent).

Per file:

1. **prepare** (Blender, a fresh interpreter): open the file, set Cycles, the resolution, the samples, seed 0,
   no denoiser, no adaptive sampling, the Standard view; a file without a camera gets one looking at its
   objects' bounding box from the front-right-above; everything else is the file's (bounces, filter, clamps,
   lights, world). Saved as a copy (relative paths remapped) that both sides read.
2. **Blender**: the copy opened as the main file and rendered (``bpy.ops.render.render``), twice: seeds 0 and
   1 -- their difference is the noise floor.
3. **blendify**: ``scene.attach_blend(copy, with_camera=True, render_settings=True)``, then ``bf.render`` with
   Cycles (``cycles_settings=`` too: the file's objects render from the file), Mitsuba and pyrender (the IR
   parse, the file's portable settings).

Metrics against Blender's seed-0 render, over RGB (premultiplied: a transparent background counts 0):
``MRE`` = mean |a - b| / mean b; the noise floor is the
MRE of Blender's seed-1 render; ``within noise`` = Cycles' MRE <= the noise floor. pyrender: SSIM of the sRGB
images (over black). The number of items the IR parse could not carry is the attach warning's count.

Run: ``nice -n 10 python benchmarks/blend_fidelity.py [--size 96x72] [--samples 64] [--only stem,...]``
(``--only``: those files re-measured, the other rows kept from the committed JSON). Writes
``benchmarks/results/blend_fidelity.md``, ``blend_fidelity.json`` and the contact sheet
``blend_fidelity.png`` (rows: files; columns: Blender, Cycles, Mitsuba, pyrender).
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
import warnings
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np
from blendify_blender.blendfile.reference import blender_render, prepare_blend

import blendify_core as bf
from blendify_core.ir.colorspace import linear_to_srgb
from blendify_core.pipeline.settings import ENGINE_LIMIT_PREFIX
from blendify_core.testing import THIRD_PARTY_DIR, THIRD_PARTY_ENV

RESULTS = Path(__file__).resolve().parent / "results"


def blend_files() -> tuple[list[Path], list[str]]:
    """The committed files, then the cache-only ones; (files, notes about what was skipped)."""
    files = sorted((THIRD_PARTY_DIR / "blend").rglob("*.blend"))
    notes = []
    cache = os.environ.get(THIRD_PARTY_ENV)
    if cache and (Path(cache) / "blend").is_dir():
        files += sorted((Path(cache) / "blend").rglob("*.blend"))
    else:
        notes.append(f"cache-only files skipped: ${THIRD_PARTY_ENV} is {'not set' if not cache else repr(cache)}")
    return files, notes


def mre(a: np.ndarray, b: np.ndarray) -> float:
    """Mean relative error of ``a`` against ``b`` over RGB (premultiplied: a transparent background is 0)."""
    return float(np.abs(a[..., :3] - b[..., :3]).mean() / max(float(np.abs(b[..., :3]).mean()), 1e-12))


def ssim(a: np.ndarray, b: np.ndarray) -> float:
    from skimage.metrics import structural_similarity

    def srgb(x: np.ndarray) -> np.ndarray:
        return np.asarray(linear_to_srgb(np.clip(x[..., :3], 0, 1)), dtype=np.float64)

    return float(structural_similarity(srgb(a), srgb(b), channel_axis=-1, data_range=1.0, win_size=7))


def measure(path: Path, work: Path, size: tuple[int, int], samples: int) -> dict[str, Any]:
    """Blender's renders and blendify's of one file (see the module)."""
    w, h = size
    copy = work / f"{path.stem}.prepared.blend"
    info = prepare_blend(path, copy, (w, h), samples)
    refs = []
    t0 = time.perf_counter()
    for seed in (0, 1):
        refs.append(blender_render(copy, work / f"{path.stem}.{seed}.exr", seed=seed)[1])
    t_blender = (time.perf_counter() - t0) / 2
    scene = bf.Scene()
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        att = scene.attach_blend(copy, with_camera=True, render_settings=True)
    lost = list(scene.attachments[-1].approximations)
    settings = {**(att.render_settings or {}), "samples": samples, "seed": 0, "outputs": ("rgba",)}
    row: dict[str, Any] = {
        "file": str(path.relative_to(path.parents[1])),
        "engine in file": info["engine"],
        "camera added": info["added_camera"],
        "renderables": len(att),
        "lights": len(att.lights),
        "ir limits": len(lost),
        "ir limit lines": lost,
        "warnings": [str(w_.message) for w_ in rec if w_.category.__name__ == "BlendAttachWarning"],
        "noise floor": mre(refs[1], refs[0]),
        "blender s": t_blender,
    }
    images = {"blender": refs[0]}
    for name, extra in (("cycles", {"cycles_settings": att.cycles_settings}), ("mitsuba", {}), ("pyrender", {})):
        t0 = time.perf_counter()
        try:
            res = bf.render(scene, backend=name, **settings, **extra)
        except bf.BlendifyError as exc:
            row[f"{name} error"] = f"{type(exc).__name__}: {exc}"
            continue
        row[f"{name} s"] = time.perf_counter() - t0
        approx = res.meta.get("approximations", [])
        row[f"{name} engine limits"] = [
            a[len(ENGINE_LIMIT_PREFIX) :] for a in approx if a.startswith(ENGINE_LIMIT_PREFIX)
        ]
        img = np.asarray(res.rgba, dtype=np.float32)
        images[name] = img
        row[f"{name} mre"] = mre(img, refs[0])
        if name == "pyrender":
            row["pyrender ssim"] = ssim(img, refs[0])
        if name == "cycles":
            row["cycles from file"] = res.meta.get("translation", {}).get("from_file")
    row["cycles within noise"] = bool(row.get("cycles mre", np.inf) <= row["noise floor"] + 1e-6)
    row["_images"] = images
    return row


_METHOD = " ".join(
    [
        "2 shared cores, timings under load). Method in the script's docstring.",
        "MRE = mean |a - b| / mean b over RGB (premultiplied) against Blender's seed-0 render;",
        "noise = the MRE of Blender's own seed-1 render; Cycles renders the attached objects from the file",
        "(`attach_blend(..., render_settings=True)` + `cycles_settings`), Mitsuba and pyrender the IR parse;",
        "'IR limits' = the lines of the attach warning (what the parse could not carry);",
        "'Mitsuba limited by the engine' = the file's biased settings Mitsuba cannot apply (its",
        '`meta["approximations"]`, `setting the engine cannot apply: ...`): a crosscheck reports such a pair as',
        "limited by the engine, not as passed or failed.",
    ]
)


def _short_limits(lines: list[str]) -> str:
    """The settings of engine-limit lines, without their explanations ('-' for none)."""
    return "; ".join(x.split(": ")[0] for x in lines) if lines else "-"


def write_results(rows: list[dict[str, Any]], notes: list[str], args: argparse.Namespace) -> None:
    from blendify_core.utils import contact_sheet

    RESULTS.mkdir(parents=True, exist_ok=True)
    if all("_images" in r for r in rows):
        tiles, labels = [], []
        for r in rows:
            for name in ("blender", "cycles", "mitsuba", "pyrender"):
                img = r["_images"].get(name)
                tiles.append(np.zeros((args.h, args.w, 4), np.float32) if img is None else img)
                labels.append(f"{Path(r['file']).stem[:16]} {name}")
        sheet = contact_sheet(tiles, labels=labels, ncols=4)
        _png(sheet)
    else:
        notes = [
            *notes,
            f"re-run with --only {args.only}: the other rows and the contact sheet are from the last full run",
        ]

    def f(v: Any, pct: bool = True) -> str:
        if v is None or (isinstance(v, float) and not np.isfinite(v)):
            return "-"
        return f"{100 * v:.2f} %" if pct else f"{v:.3f}"

    lines = [
        "# .blend fidelity: third-party files, Blender's own render against blendify's",
        "",
        f"`nice -n 10 python benchmarks/blend_fidelity.py --size {args.w}x{args.h} --samples {args.samples}` "
        f"({time.strftime('%Y-%m-%d')}, bpy {metadata.version('bpy')}, Mitsuba {metadata.version('mitsuba')}; "
        + _METHOD,
        "",
        "| file | engine in file | objects / lights | IR limits | noise | Cycles MRE | within noise | Mitsuba MRE "
        "| Mitsuba limited by the engine | pyrender MRE | pyrender SSIM |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        cells = [
            f"{r['file']}{' (camera added)' if r['camera added'] else ''}",
            r["engine in file"],
            f"{r['renderables']} / {r['lights']}",
            str(r["ir limits"]),
            f(r["noise floor"]),
            f(r.get("cycles mre")),
            "yes" if r["cycles within noise"] else "NO",
            f(r.get("mitsuba mre")),
            _short_limits(r.get("mitsuba engine limits", [])),
            f(r.get("pyrender mre")),
            f(r.get("pyrender ssim"), pct=False),
        ]
        lines.append("| " + " | ".join(cells) + " |")
    n_ok = sum(r["cycles within noise"] for r in rows)
    lines += ["", f"Cycles within noise of Blender on {n_ok} of {len(rows)} files.", ""]
    lines += [f"- {n}" for n in notes]
    errors = [(r["file"], k, v) for r in rows for k, v in r.items() if k.endswith(" error")]
    lines += [f"- {fname}: {k}: {v}" for fname, k, v in errors]
    lines += ["", "![contact sheet: per file Blender, Cycles, Mitsuba, pyrender](blend_fidelity.png)", ""]
    lines += ["## What the IR parse could not carry (per file)", ""]
    for r in rows:
        lines.append(f"- **{r['file']}**: " + ("; ".join(r["ir limit lines"]) if r["ir limit lines"] else "nothing"))
    (RESULTS / "blend_fidelity.md").write_text("\n".join(lines) + "\n")
    data = [{k: v for k, v in r.items() if not k.startswith("_")} for r in rows]
    (RESULTS / "blend_fidelity.json").write_text(json.dumps(data, indent=1, default=str) + "\n")


def _png(sheet: np.ndarray) -> None:
    from PIL import Image

    Image.fromarray(sheet).save(RESULTS / "blend_fidelity.png")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="96x72", help="W x H of every render")
    ap.add_argument("--samples", type=int, default=64)
    ap.add_argument("--only", default="", help="comma-separated file stems")
    args = ap.parse_args()
    args.w, args.h = (int(x) for x in args.size.lower().split("x"))
    files, notes = blend_files()
    if args.only:
        files = [p for p in files if p.stem in args.only.split(",")]
    rows = []
    with tempfile.TemporaryDirectory(prefix="blend_fidelity_") as tmp:
        for p in files:
            print(f"{p.name} ...", flush=True)
            row = measure(p, Path(tmp), (args.w, args.h), args.samples)
            nan = float("nan")
            print(
                "  " + ", ".join(f"{k} {row.get(k, nan):.4f}" for k in ("noise floor", "cycles mre", "mitsuba mre")),
                flush=True,
            )
            rows.append(row)
    if args.only and (RESULTS / "blend_fidelity.json").is_file():  # the other rows from the committed results
        new = {r["file"]: r for r in rows}
        old = json.loads((RESULTS / "blend_fidelity.json").read_text())
        rows = [new.pop(r["file"], r) for r in old] + list(new.values())
    write_results(rows, notes, args)


if __name__ == "__main__":
    main()
