"""Bad input never crashes or lies: a table of distinct bad inputs across the public API and the CLI.

Each raises the documented error type (InvalidSceneError is a ValueError, UnsupportedFeatureError,
BackendUnavailableError is an ImportError; the CLI prints one line and exits non-zero) with a message that
names the argument, and leaves no file behind in the output folder. The CLI runs in a subprocess with a
timeout, so a segfault, an abort, a hang or a stray traceback would show. Complements
tests/core/test_core_validation.py (IR constructors), which this table does not repeat.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import blendify_core as bf
from blendify_core.utils import Trajectory, estimate_normals

REPO = Path(__file__).resolve().parents[2]
CLI_TIMEOUT = 180


@dataclass(frozen=True)
class Bad:
    """One bad input: ``call(ctx)`` must raise ``exc`` with every word of ``words`` in the message."""

    id: str
    what: str
    call: Callable[[Any], Any]
    exc: type[BaseException] | tuple[type[BaseException], ...]
    words: tuple[str, ...]
    backend: str | None = None  # the engine it needs (skipped when unavailable)


class Ctx:
    """Per-test folders: ``inp`` holds prepared inputs, ``out`` must stay empty after the failure."""

    def __init__(self, tmp: Path):
        self.inp = tmp / "in"
        self.out = tmp / "out"
        self.inp.mkdir()
        self.out.mkdir()

    def file(self, name: str, data: bytes) -> Path:
        p = self.inp / name
        p.write_bytes(data)
        return p

    def scene_file(self, scene: bf.Scene | None = None, name: str = "scene.npz") -> Path:
        p = self.inp / name
        (scene or small_scene()).save(p)
        return p


def small_scene(resolution=(16, 12)) -> bf.Scene:
    scene = bf.Scene()
    scene.renderables.add_sphere_nurbs(0.5, bf.DiffuseMaterial(), bf.UniformColors((0.5, 0.5, 0.5)), tag="ball")
    scene.set_perspective_camera(resolution, fov_x=np.deg2rad(40), translation=(0, 0, 4))
    scene.lights.add_point(100.0, translation=(0, 2, 3))
    return scene


def result(resolution=(16, 12), depth=True) -> bf.RenderResult:
    w, h = resolution
    return bf.RenderResult(
        rgba=np.zeros((h, w, 4), np.float32),
        depth=np.full((h, w), np.inf, np.float32) if depth else None,
        meta={"backend": "pyrender"},
    )


def render(backend: str = "pyrender", scene: bf.Scene | None = None, **kw: Any) -> bf.RenderResult:
    kw.setdefault("samples", 1)
    return bf.render(scene or small_scene(), backend=backend, **kw)


def uv_quad_scene(colors: Any, material: Any = None) -> bf.Scene:
    scene = small_scene()
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
    uv = None if isinstance(colors, bf.FileTextureColors) else UV
    scene.renderables.add_mesh(v, [[0, 1, 2, 3]], material or bf.DiffuseMaterial(), colors, uv_map=uv, tag="quad")
    return scene


UV = bf.VertexUV([[0, 0], [1, 0], [1, 1], [0, 1]])
PNG_1X1 = bytes.fromhex(
    "89504e470d0a1a0a0000000d4948445200000001000000010802000000907753de0000000c4944415408d763f8cfc0000003"
    "010100c9fe92ef0000000049454e44ae426082"
)


def corrupt_texture_render(backend: str) -> Callable[[Ctx], Any]:
    def run(ctx: Ctx) -> Any:
        bad = ctx.file("broken.png", PNG_1X1[:40] + b"\x00garbage" * 8)
        return render(backend, scene=uv_quad_scene(bf.FileTextureColors(bad, UV)))

    return run


def corrupt_texture_map(ctx: Ctx) -> Any:
    bad = ctx.file("rough.png", b"not an image at all")
    material = bf.PrincipledBSDFMaterial(roughness_map=bf.TextureMap(bad))
    return render(scene=uv_quad_scene(bf.UniformColors((0.5, 0.5, 0.5)), material))


def area_light_strict(ctx: Ctx) -> Any:
    scene = small_scene()
    scene.lights.add_area("circle", 0.5, 50.0, translation=(0, 0, 3))
    return render("pyrender", scene=scene, strict=True)


def options_on_instance(ctx: Ctx) -> Any:
    with bf.get_backend("pyrender") as inst:
        return bf.render(small_scene(), backend=inst, samples=1, platform="egl")


def job(**kw: Any) -> Callable[[Ctx], Any]:
    def make(ctx: Ctx) -> Any:
        args = {"scene_or_path": small_scene(), "output": ctx.out / "a.png", **kw}
        return bf.RenderJob(args.pop("scene_or_path"), args.pop("output"), **args)

    return make


def many(**kw: Any) -> Callable[[Ctx], Any]:
    def run(ctx: Ctx) -> Any:
        jobs = kw.pop("jobs", None)
        if jobs is None:
            jobs = [bf.RenderJob(small_scene(), ctx.out / "a.png", backend="pyrender", samples=1)]
        return bf.render_many(jobs, progress=False, manifest=False, **kw)

    return run


def read_jobs_file(text: str) -> Callable[[Ctx], Any]:
    def run(ctx: Ctx) -> Any:
        from blendify_core.batch.run import read_jobs

        return read_jobs(ctx.file("jobs.jsonl", text.encode()))

    return run


def traj(*keypoints: Any) -> Trajectory:
    return Trajectory(list(keypoints))


POINTS = np.random.default_rng(0).normal(size=(20, 3))

API: list[Bad] = [
    # -- render(): settings and backend options at render time -------------------------------------
    Bad("render-samples-float", "samples=2.5", lambda c: render(samples=2.5), bf.InvalidSceneError, ("samples",)),
    Bad("render-samples-bool", "samples=True", lambda c: render(samples=True), bf.InvalidSceneError, ("samples",)),
    Bad("render-seed-string", "seed='abc'", lambda c: render(seed="abc"), bf.InvalidSceneError, ("seed",)),
    Bad("render-threads-zero", "threads=0", lambda c: render(threads=0), bf.InvalidSceneError, ("threads",)),
    Bad(
        "render-outputs-nope",
        "outputs=('nope',)",
        lambda c: render(outputs=("nope",)),
        bf.InvalidSceneError,
        ("outputs", "nope"),
    ),
    Bad(
        "render-outputs-not-names",
        "outputs=(1, 2)",
        lambda c: render(outputs=(1, 2)),
        bf.InvalidSceneError,
        ("outputs",),
    ),
    Bad("render-strict-not-bool", "strict='yes'", lambda c: render(strict="yes"), bf.InvalidSceneError, ("strict",)),
    Bad(
        "render-max-bounces-negative",
        "max_bounces=-1",
        lambda c: render(max_bounces=-1),
        bf.InvalidSceneError,
        ("max_bounces",),
    ),
    Bad(
        "render-pixel-filter-unknown",
        "pixel_filter='sinc9'",
        lambda c: render(pixel_filter="sinc9"),
        bf.InvalidSceneError,
        ("pixel_filter",),
    ),
    Bad(
        "render-time-limit-negative",
        "time_limit=-1",
        lambda c: render(time_limit=-1.0),
        bf.InvalidSceneError,
        ("time_limit",),
    ),
    Bad(
        "render-target-error-zero",
        "target_error=0",
        lambda c: render(target_error=0.0),
        bf.InvalidSceneError,
        ("target_error",),
    ),
    Bad(
        "render-denoise-string",
        "denoise='maybe'",
        lambda c: render(denoise="maybe"),
        bf.InvalidSceneError,
        ("denoise",),
    ),
    Bad(
        "render-unknown-option",
        "an unknown keyword (colour='red')",
        lambda c: render(colour="red"),
        bf.InvalidSceneError,
        ("colour",),
    ),
    Bad(
        "render-options-on-instance",
        "backend options with a backend instance",
        options_on_instance,
        bf.InvalidSceneError,
        ("platform",),
        "pyrender",
    ),
    Bad(
        "pyrender-platform-nonsense",
        "pyrender platform='nonsense'",
        lambda c: render(platform="nonsense"),
        bf.InvalidSceneError,
        ("platform", "nonsense"),
        "pyrender",
    ),
    Bad(
        "mitsuba-variant-nonsense",
        "mitsuba variant='nonsense'",
        lambda c: render("mitsuba", variant="nonsense"),
        bf.InvalidSceneError,
        ("variant", "nonsense"),
        "mitsuba",
    ),
    Bad(
        "cycles-device-nonsense",
        "cycles device='nonsense'",
        lambda c: render("cycles", device="nonsense"),
        bf.InvalidSceneError,
        ("device", "nonsense"),
        "cycles",
    ),
    Bad(
        "cycles-unknown-option",
        "cycles option 'frobnicate'",
        lambda c: render("cycles", frobnicate=1),
        bf.InvalidSceneError,
        ("frobnicate",),
        "cycles",
    ),
    Bad(
        "strict-approximation",
        "strict=True with a feature pyrender approximates (area light)",
        area_light_strict,
        bf.UnsupportedFeatureError,
        ("strict", "approximates"),
        "pyrender",
    ),
    Bad(
        "render-seed-too-large",
        "seed=2**31 (engines take 32-bit signed seeds)",
        lambda c: render(seed=2**31),
        bf.InvalidSceneError,
        ("seed", "2147483647"),
    ),
    Bad(
        "render-samples-huge",
        "samples=10**12",
        lambda c: render(samples=10**12),
        bf.InvalidSceneError,
        ("samples",),
    ),
    Bad(
        "render-outputs-comma-string",
        "outputs='rgb,nope' (one string, not a tuple)",
        lambda c: render(outputs="rgb,nope"),
        bf.InvalidSceneError,
        ("outputs", "rgb,nope"),
    ),
    Bad(
        "render-distortion-folds-over",
        "a distortion that cannot be inverted over the image (k1=-0.6, k2=0.4 at 90 degrees fov)",
        lambda c: render(scene=_distorted()),
        bf.InvalidSceneError,
        ("distortion", "inverted"),
        "pyrender",
    ),
    Bad(
        "scene-with-camera-not-a-camera",
        "Scene.with_camera('cam')",
        lambda c: small_scene().with_camera("cam"),
        bf.InvalidSceneError,
        ("camera", "str"),
    ),
    Bad(
        "get-backend-unknown",
        "get_backend('povray')",
        lambda c: bf.get_backend("povray"),
        bf.InvalidSceneError,
        ("backend", "povray"),
    ),
    Bad(
        "pyrender-platform-int",
        "get_backend('pyrender', platform=3)",
        lambda c: bf.get_backend("pyrender", platform=3),
        bf.InvalidSceneError,
        ("platform",),
        "pyrender",
    ),
    # -- textures from files ------------------------------------------------------------------------
    Bad(
        "texture-file-missing",
        "FileTextureColors of a missing file",
        lambda c: bf.FileTextureColors(c.inp / "missing.png", UV),
        bf.InvalidSceneError,
        ("texture_path", "missing.png"),
    ),
    Bad(
        "texture-file-is-a-folder",
        "FileTextureColors of a folder",
        lambda c: bf.FileTextureColors(c.inp, UV),
        bf.InvalidSceneError,
        ("texture_path",),
    ),
    Bad(
        "texture-file-corrupt-pyrender",
        "a truncated PNG as FileTextureColors, rendered by pyrender",
        corrupt_texture_render("pyrender"),
        (bf.InvalidSceneError, bf.RenderError),
        ("texture_path", "broken.png"),
        "pyrender",
    ),
    Bad(
        "texture-file-corrupt-mitsuba",
        "a truncated PNG as FileTextureColors, rendered by mitsuba",
        corrupt_texture_render("mitsuba"),
        (bf.InvalidSceneError, bf.RenderError),
        ("texture_path", "broken.png"),
        "mitsuba",
    ),
    Bad(
        "texture-file-corrupt-cycles",
        "a truncated PNG as FileTextureColors, rendered by cycles",
        corrupt_texture_render("cycles"),
        (bf.InvalidSceneError, bf.RenderError),
        ("texture_path", "broken.png"),
        "cycles",
    ),
    Bad(
        "texture-map-corrupt-render",
        "a roughness TextureMap from a file that is not an image, rendered",
        corrupt_texture_map,
        (bf.InvalidSceneError, bf.RenderError),
        ("rough.png",),
        "pyrender",
    ),
    # -- .blend attachment --------------------------------------------------------------------------
    Bad(
        "attach-blend-not-a-blend",
        "attach_blend of a text file named .blend",
        lambda c: small_scene().attach_blend(c.file("fake.blend", b"hello, not a blend file\n")),
        bf.InvalidSceneError,
        ("path", "fake.blend"),
        "cycles",
    ),
    Bad(
        "attach-blend-missing",
        "attach_blend of a missing file",
        lambda c: small_scene().attach_blend(c.inp / "nothing.blend"),
        bf.InvalidSceneError,
        ("path", "nothing.blend"),
        "cycles",
    ),
    # -- saving results and scenes ------------------------------------------------------------------
    Bad(
        "result-save-missing-folder",
        "RenderResult.save into a missing folder",
        lambda c: result().save(c.out / "missing" / "x.png"),
        bf.InvalidSceneError,
        ("path", "missing"),
    ),
    Bad(
        "result-save-bad-suffix",
        "RenderResult.save as .jpg",
        lambda c: result().save(c.out / "x.jpg"),
        bf.InvalidSceneError,
        ("path", ".png"),
    ),
    Bad(
        "result-save-unknown-output",
        "RenderResult.save output='nope'",
        lambda c: result().save(c.out / "x.png", output="nope"),
        bf.InvalidSceneError,
        ("output", "nope"),
    ),
    Bad(
        "result-save-absent-output",
        "RenderResult.save of an output that was not rendered",
        lambda c: result(depth=False).save(c.out / "x.png", output="depth"),
        bf.InvalidSceneError,
        ("depth",),
    ),
    Bad(
        "scene-save-missing-folder",
        "Scene.save into a missing folder",
        lambda c: small_scene().save(c.out / "missing" / "s.npz"),
        bf.InvalidSceneError,
        ("path", "missing"),
    ),
    Bad(
        "scene-save-bad-suffix",
        "Scene.save as .json",
        lambda c: small_scene().save(c.out / "s.json"),
        bf.InvalidSceneError,
        ("path",),
    ),
    # -- loading scene files ------------------------------------------------------------------------
    Bad(
        "scene-load-random-bytes",
        "Scene.load of random bytes",
        lambda c: bf.Scene.load(c.file("s.npz", os.urandom(256))),
        bf.InvalidSceneError,
        ("path", "s.npz"),
    ),
    Bad(
        "scene-load-truncated",
        "Scene.load of a truncated scene file",
        lambda c: bf.Scene.load(c.file("t.npz", c.scene_file().read_bytes()[:300])),
        bf.InvalidSceneError,
        ("path", "t.npz"),
    ),
    Bad(
        "scene-load-png",
        "Scene.load of a PNG",
        lambda c: bf.Scene.load(c.file("p.npz", PNG_1X1)),
        bf.InvalidSceneError,
        ("path", "p.npz"),
    ),
    Bad(
        "scene-load-missing-texture",
        "a scene file whose texture was deleted",
        lambda c: _missing_texture(c),
        bf.InvalidSceneError,
        ("tex.png",),
    ),
    # -- batch --------------------------------------------------------------------------------------
    Bad("job-output-jpg", "RenderJob output .jpg", job(output="a.jpg"), bf.InvalidSceneError, ("output", ".jpg")),
    Bad("job-scene-int", "RenderJob scene 42", job(scene_or_path=42), bf.InvalidSceneError, ("scene_or_path",)),
    Bad(
        "job-scene-not-npz",
        "RenderJob scene path .obj",
        job(scene_or_path="a.obj"),
        bf.InvalidSceneError,
        ("scene_or_path", ".npz"),
    ),
    Bad("job-backend-int", "RenderJob backend=3", job(backend=3), bf.InvalidSceneError, ("backend",)),
    Bad(
        "job-option-not-json",
        "RenderJob backend option that is not JSON",
        job(platform=object()),
        bf.InvalidSceneError,
        ("render_kwargs", "JSON"),
    ),
    Bad("job-quality-unknown", "RenderJob quality='ultra'", job(quality="ultra"), bf.InvalidSceneError, ("quality",)),
    Bad(
        "job-from-dict-missing-output",
        "RenderJob.from_dict without output",
        lambda c: bf.RenderJob.from_dict({"scene": "a.npz"}),
        bf.InvalidSceneError,
        ("output",),
    ),
    Bad(
        "read-jobs-missing",
        "read_jobs of a missing file",
        lambda c: __import__("blendify_core.batch.run").batch.read_jobs(c.inp / "none.jsonl"),
        bf.InvalidSceneError,
        ("jobs", "none.jsonl"),
    ),
    Bad(
        "read-jobs-corrupt-json",
        "a jobs file with a broken JSON line",
        read_jobs_file('{"scene": "a.npz",\n'),
        bf.InvalidSceneError,
        ("line 1",),
    ),
    Bad(
        "render-many-not-jobs",
        "render_many of scenes instead of jobs",
        many(jobs=[small_scene()]),
        bf.InvalidSceneError,
        ("jobs",),
    ),
    Bad(
        "render-many-executor",
        "render_many executor='nonsense'",
        many(executor="nonsense"),
        bf.InvalidSceneError,
        ("executor", "nonsense"),
    ),
    Bad("render-many-workers-zero", "render_many workers=0", many(workers=0), bf.InvalidSceneError, ("workers",)),
    Bad(
        "render-many-timeout-negative", "render_many timeout=-1", many(timeout=-1.0), bf.InvalidSceneError, ("timeout",)
    ),
    Bad(
        "render-many-recycle-zero",
        "render_many recycle_after=0",
        many(recycle_after=0),
        bf.InvalidSceneError,
        ("recycle_after",),
    ),
    # -- compare / crosscheck -----------------------------------------------------------------------
    Bad(
        "crosscheck-outputs-unknown",
        "crosscheck outputs=('nope',)",
        lambda c: bf.crosscheck(small_scene(), backends=("pyrender",), outputs=("nope",), samples=1),
        bf.InvalidSceneError,
        ("outputs", "nope"),
    ),
    Bad(
        "compare-tier-metric-unknown",
        "compare() tier dict with an unknown metric",
        lambda c: bf.compare(result(), result(), tier={"rgb": {"nope": 1.0}}),
        bf.InvalidSceneError,
        ("tier", "nope"),
    ),
    Bad(
        "compare-resolution-mismatch",
        "compare() of 16x12 and 32x24 results",
        lambda c: bf.compare(result(), result((32, 24))),
        bf.InvalidSceneError,
        ("resolution",),
    ),
    Bad(
        "compare-not-results",
        "compare() of arrays",
        lambda c: bf.compare(np.zeros(3), np.zeros(3)),
        bf.InvalidSceneError,
        ("RenderResult",),
    ),
    Bad(
        "compare-tier-unknown",
        "compare() tier='nonsense'",
        lambda c: bf.compare(result(), result(), tier="x9"),
        bf.InvalidSceneError,
        ("tier", "x9"),
    ),
    Bad(
        "compare-output-missing",
        "compare() of an output neither result has",
        lambda c: bf.compare(result(), result(), outputs=("normal",)),
        bf.InvalidSceneError,
        ("normal",),
    ),
    Bad(
        "crosscheck-repeats-zero",
        "crosscheck repeats=0",
        lambda c: bf.crosscheck(small_scene(), backends=("pyrender",), samples=1, repeats=0),
        bf.InvalidSceneError,
        ("repeats",),
    ),
    Bad(
        "crosscheck-fixed-setting",
        "crosscheck pixel_filter='gaussian' (fixed by crosscheck)",
        lambda c: bf.crosscheck(small_scene(), backends=("pyrender",), pixel_filter="gaussian"),
        bf.InvalidSceneError,
        ("pixel_filter",),
    ),
    # -- utilities ----------------------------------------------------------------------------------
    Bad(
        "texture-deleted-before-render",
        "a FileTextureColors whose file is deleted before rendering",
        lambda c: _deleted_texture_render(c),
        bf.InvalidSceneError,
        ("texture_path", "gone.png"),
        "pyrender",
    ),
    Bad(
        "trajectory-sample-decreasing",
        "Trajectory.sample at decreasing times",
        lambda c: traj(((0, 0, 0),), ((1, 0, 0),)).sample([1.0, 0.0]),
        bf.InvalidSceneError,
        ("times",),
    ),
    Bad(
        "trajectory-interpolation-unknown",
        "Trajectory.sample interpolation='quintic'",
        lambda c: traj(((0, 0, 0),), ((1, 0, 0),)).sample([0.5], interpolation="quintic"),
        bf.InvalidSceneError,
        ("interpolation", "quintic"),
    ),
    Bad(
        "contact-sheet-seven-channels",
        "contact_sheet of a 7-channel image",
        lambda c: __import__("blendify_core.utils", fromlist=["contact_sheet"]).contact_sheet([np.zeros((4, 4, 7))]),
        bf.InvalidSceneError,
        ("images[0]",),
    ),
    Bad(
        "trajectory-position-2d",
        "Trajectory keypoint position of 2 values",
        lambda c: traj(((0, 0),)),
        bf.InvalidSceneError,
        ("position",),
    ),
    Bad(
        "trajectory-position-nan",
        "Trajectory keypoint position NaN",
        lambda c: traj(((0, np.nan, 0),)),
        bf.InvalidSceneError,
        ("position",),
    ),
    Bad(
        "trajectory-rotation-mode",
        "Trajectory keypoint rotation_mode 'axisangle'",
        lambda c: traj({"position": (0, 0, 0), "rotation": (1, 0, 0), "rotation_mode": "axisangle"}),
        bf.InvalidSceneError,
        ("rotation_mode",),
    ),
    Bad(
        "trajectory-time-nan",
        "Trajectory keypoint time NaN",
        lambda c: traj(((0, 0, 0), None, float("nan"))),
        bf.InvalidSceneError,
        ("time",),
    ),
    Bad(
        "trajectory-remove-out-of-range",
        "Trajectory.remove_keypoint(5) of 1 keypoint",
        lambda c: traj(((0, 0, 0),)).remove_keypoint(5),
        bf.InvalidSceneError,
        ("index",),
    ),
    Bad(
        "trajectory-empty-sample",
        "an empty Trajectory sampled",
        lambda c: Trajectory().sample(0.0),
        bf.InvalidSceneError,
        ("keypoint",),
    ),
    Bad(
        "normals-2d-points",
        "estimate_normals of (N, 2) points",
        lambda c: estimate_normals(POINTS[:, :2]),
        bf.InvalidSceneError,
        ("points",),
    ),
    Bad(
        "normals-nan-points",
        "estimate_normals with a NaN point",
        lambda c: estimate_normals(np.vstack([POINTS, [np.nan, 0, 0]])),
        bf.InvalidSceneError,
        ("points",),
    ),
    Bad(
        "normals-k-zero", "estimate_normals k=0", lambda c: estimate_normals(POINTS, k=0), bf.InvalidSceneError, ("k",)
    ),
    Bad(
        "normals-orient-unknown",
        "estimate_normals orient='up'",
        lambda c: estimate_normals(POINTS, orient="up"),
        bf.InvalidSceneError,
        ("orient",),
    ),
    Bad(
        "normals-viewpoint-shape",
        "estimate_normals viewpoint of 2 values",
        lambda c: estimate_normals(POINTS, orient="viewpoint", viewpoint=(0, 0)),
        bf.InvalidSceneError,
        ("viewpoint",),
    ),
    Bad(
        "normals-viewpoint-missing",
        "estimate_normals orient='viewpoint' without a viewpoint",
        lambda c: estimate_normals(POINTS, orient="viewpoint"),
        bf.InvalidSceneError,
        ("viewpoint",),
    ),
]


def _distorted() -> bf.Scene:
    scene = small_scene()
    scene.set_perspective_camera(
        (16, 12), fov_x=np.deg2rad(90), translation=(0, 0, 4), distortion=(-0.6, 0.4, 0.0, 0.0)
    )
    return scene


def _deleted_texture_render(ctx: Ctx) -> Any:
    tex = ctx.file("gone.png", PNG_1X1)
    scene = uv_quad_scene(bf.FileTextureColors(tex, UV))
    tex.unlink()
    return render(scene=scene)


def _missing_texture(ctx: Ctx) -> Any:
    tex = ctx.file("tex.png", PNG_1X1)
    path = ctx.scene_file(uv_quad_scene(bf.FileTextureColors(tex, UV)))
    tex.unlink()
    return bf.Scene.load(path)


def _skip_unavailable(name: str | None) -> None:
    if name is None:
        return
    status = bf.available_backends().get(name)
    if status is None or not status.available:
        reason = f"backend {name!r} unavailable: {status.reason if status else 'not registered'}"
        print(f"SKIP: {reason}")
        pytest.skip(reason)


def _listing(folder: Path) -> list[str]:
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*"))


@pytest.mark.parametrize("case", API, ids=[c.id for c in API])
def test_bad_api_input(case: Bad, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    _skip_unavailable(case.backend)
    ctx = Ctx(tmp_path)
    monkeypatch.chdir(ctx.out)  # relative output names land in `out`, which must stay empty
    with pytest.raises(case.exc) as info:
        case.call(ctx)
    assert not isinstance(info.value, (SystemExit, AssertionError, KeyboardInterrupt))
    message = str(info.value)
    for word in case.words:
        assert word.lower() in message.lower(), f"message does not name {word!r}: {message}"
    assert _listing(ctx.out) == [], f"files left behind: {_listing(ctx.out)}"


def test_error_types_are_the_documented_builtins() -> None:
    """InvalidSceneError is a ValueError, BackendUnavailableError an ImportError, RenderError a RuntimeError."""
    assert issubclass(bf.InvalidSceneError, ValueError)
    assert issubclass(bf.BackendUnavailableError, ImportError)
    assert issubclass(bf.RenderError, RuntimeError)
    assert issubclass(bf.UnsupportedFeatureError, bf.BlendifyError)


def test_api_table_is_large_and_distinct() -> None:
    """At least 50 distinct bad inputs (API + CLI), no duplicate ids."""
    ids = [c.id for c in API] + [c.id for c in CLI]
    assert len(ids) == len(set(ids))
    assert len(ids) >= 50


# -- the CLI ----------------------------------------------------------------------------------------


@dataclass(frozen=True)
class BadCli:
    id: str
    what: str
    argv: Callable[[Ctx], list[str]]
    words: tuple[str, ...]
    backend: str | None = None


def _jobs(ctx: Ctx, lines: list[Any]) -> str:
    p = ctx.inp / "jobs.jsonl"
    p.write_text("\n".join(x if isinstance(x, str) else json.dumps(x) for x in lines) + "\n")
    return str(p)


def _texture_scene_without_texture(ctx: Ctx) -> str:
    tex = ctx.file("tex.png", PNG_1X1)
    path = ctx.scene_file(uv_quad_scene(bf.FileTextureColors(tex, UV)))
    tex.unlink()
    return str(path)


CLI: list[BadCli] = [
    BadCli("cli-no-such-command", "an unknown sub-command", lambda c: ["paint"], ("paint",)),
    BadCli(
        "cli-unknown-flag",
        "render --frobnicate",
        lambda c: ["render", str(c.scene_file()), "--frobnicate"],
        ("frobnicate",),
    ),
    BadCli(
        "cli-backend-unknown",
        "render -b povray",
        lambda c: ["render", str(c.scene_file()), "-b", "povray", "-o", str(c.out / "r.png")],
        ("povray",),
    ),
    BadCli(
        "cli-quality-unknown",
        "render -q ultra",
        lambda c: ["render", str(c.scene_file()), "-q", "ultra"],
        ("quality", "ultra"),
    ),
    BadCli(
        "cli-outputs-nonsense",
        "render --outputs rgb,flow",
        lambda c: [
            "render",
            str(c.scene_file()),
            "-b",
            "pyrender",
            "--outputs",
            "rgb,flow",
            "-o",
            str(c.out / "r.png"),
        ],
        ("outputs", "flow"),
    ),
    BadCli(
        "cli-outputs-empty",
        "render --outputs ','",
        lambda c: ["render", str(c.scene_file()), "-b", "pyrender", "--outputs", ",", "-o", str(c.out / "r.png")],
        ("outputs",),
    ),
    BadCli("cli-samples-zero", "render -s 0", lambda c: ["render", str(c.scene_file()), "-s", "0"], ("samples",)),
    BadCli(
        "cli-samples-text",
        "render -s many",
        lambda c: ["render", str(c.scene_file()), "-s", "many"],
        ("samples", "many"),
    ),
    BadCli(
        "cli-scene-missing",
        "render of a missing scene file",
        lambda c: ["render", str(c.inp / "nope.npz"), "-o", str(c.out / "r.png")],
        ("nope.npz",),
    ),
    BadCli(
        "cli-scene-corrupt",
        "render of a corrupt scene file",
        lambda c: ["render", str(c.file("bad.npz", os.urandom(512))), "-o", str(c.out / "r.png")],
        ("bad.npz",),
    ),
    BadCli(
        "cli-scene-is-png",
        "render of a PNG named .npz",
        lambda c: ["render", str(c.file("img.npz", PNG_1X1)), "-o", str(c.out / "r.png")],
        ("img.npz",),
    ),
    BadCli(
        "cli-scene-unreadable",
        "render of a scene file without read permission",
        lambda c: ["render", str(_unreadable(c)), "-o", str(c.out / "r.png")],
        ("locked.npz",),
    ),
    BadCli(
        "cli-scene-texture-missing",
        "render of a scene whose texture file was deleted",
        lambda c: ["render", _texture_scene_without_texture(c), "-o", str(c.out / "r.png")],
        ("tex.png",),
    ),
    BadCli(
        "cli-output-missing-folder",
        "render -o into a missing folder",
        lambda c: ["render", str(c.scene_file()), "-b", "pyrender", "-o", str(c.out / "no" / "r.png")],
        ("--output", "does not exist"),
        "pyrender",
    ),
    BadCli(
        "cli-output-checked-before-render",
        "render -o into a missing folder: the output is checked before any rendering (-b takes only registered "
        "backends, so the scene is sent to one that would render; the error comes first)",
        lambda c: ["render", str(c.scene_file()), "-b", "pyrender", "-o", str(c.out / "no" / "r.png")],
        ("--output", "does not exist"),
    ),
    BadCli(
        "cli-output-jpg",
        "render -o r.jpg",
        lambda c: ["render", str(c.scene_file()), "-b", "pyrender", "-o", str(c.out / "r.jpg")],
        ("--output", ".jpg"),
        "pyrender",
    ),
    BadCli(
        "cli-scene-without-camera",
        "render of a scene file without a camera",
        lambda c: ["render", str(c.scene_file(_no_camera())), "-b", "pyrender", "-o", str(c.out / "r.png")],
        ("camera",),
        "pyrender",
    ),
    BadCli(
        "cli-seed-negative",
        "render --seed -5",
        lambda c: ["render", str(c.scene_file()), "-b", "pyrender", "--seed", "-5", "-o", str(c.out / "r.png")],
        ("seed",),
        "pyrender",
    ),
    BadCli(
        "cli-demo-backend-unknown",
        "demo -b povray",
        lambda c: ["demo", "-b", "povray", "--size", "16", "-o", str(c.out / "d.png")],
        ("povray",),
    ),
    BadCli(
        "cli-demo-size-zero", "demo --size 0", lambda c: ["demo", "--size", "0", "-o", str(c.out / "d.png")], ("size",)
    ),
    BadCli(
        "cli-batch-missing-jobs",
        "batch of a missing jobs file",
        lambda c: ["batch", str(c.inp / "j.jsonl")],
        ("j.jsonl",),
    ),
    BadCli(
        "cli-batch-corrupt-jobs",
        "batch of a jobs file with a broken line",
        lambda c: ["batch", _jobs(c, ['{"scene": "a.npz"'])],
        ("line 1",),
    ),
    BadCli(
        "cli-batch-job-without-output",
        "batch job without 'output'",
        lambda c: ["batch", _jobs(c, [{"scene": "a.npz"}])],
        ("output",),
    ),
    BadCli(
        "cli-batch-executor",
        "batch --executor nonsense",
        lambda c: [
            "batch",
            _jobs(c, [{"scene": "scene.npz", "output": str(c.out / "a.png")}]),
            "--executor",
            "nonsense",
            "--no-progress",
        ],
        ("executor", "nonsense"),
    ),
    BadCli(
        "cli-batch-workers-zero",
        "batch --workers 0",
        lambda c: [
            "batch",
            _jobs(c, [{"scene": "scene.npz", "output": str(c.out / "a.png")}]),
            "--workers",
            "0",
            "--no-progress",
        ],
        ("workers",),
    ),
    BadCli(
        "cli-crosscheck-missing-scene",
        "crosscheck of a missing scene file",
        lambda c: ["crosscheck", str(c.inp / "x.npz")],
        ("x.npz",),
    ),
]


def _no_camera() -> bf.Scene:
    scene = bf.Scene()
    scene.renderables.add_sphere_nurbs(0.5, bf.DiffuseMaterial(), bf.UniformColors((0.5, 0.5, 0.5)), tag="ball")
    return scene


def _unreadable(ctx: Ctx) -> Path:
    p = ctx.scene_file(name="locked.npz")
    p.chmod(0)
    if os.access(p, os.R_OK):  # running as root: permissions do not bind; use a folder instead
        p.chmod(0o644)
        p.unlink()
        p.mkdir()
    return p


@pytest.mark.parametrize("case", CLI, ids=[c.id for c in CLI])
def test_bad_cli_input(case: BadCli, tmp_path: Path) -> None:
    _skip_unavailable(case.backend)
    ctx = Ctx(tmp_path)
    argv = case.argv(ctx)
    env = {**os.environ, "PYTHONFAULTHANDLER": "1"}
    proc = subprocess.run(
        [sys.executable, "-m", "blendify_core", *argv],
        cwd=ctx.out,
        capture_output=True,
        text=True,
        timeout=CLI_TIMEOUT,
        env=env,
    )
    assert proc.returncode not in (0,), f"exit code 0 for bad input; stdout={proc.stdout!r}"
    assert proc.returncode > 0, f"killed by signal {-proc.returncode}: {proc.stderr[-2000:]}"
    err = proc.stderr.strip()
    assert "Traceback" not in err, f"a traceback instead of a one-line error:\n{err[-3000:]}"
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, f"expected a one-line error, got {len(lines)} lines:\n{err[-3000:]}"
    assert lines[0].startswith("blendify"), lines[0]
    for word in case.words:
        assert word.lower() in lines[0].lower(), f"message does not name {word!r}: {lines[0]}"
    assert _listing(ctx.out) == [], f"files left behind: {_listing(ctx.out)}"


@pytest.mark.parametrize(
    ("outputs", "suffix", "files"),
    [
        ("depth", ".png", ["r.png"]),
        ("depth,normal", ".png", ["r.normal.png", "r.png"]),
        ("rgb,depth", ".exr", ["r.depth.exr", "r.exr"]),
    ],
)
def test_cli_render_without_rgb_writes_the_requested_outputs(outputs, suffix, files, tmp_path):
    """`blendify render --outputs depth` writes the depth image (it failed after rendering: no 'rgb'), and
    .exr gets one file per output like .png (extra outputs were dropped), the same files as a batch job."""
    _skip_unavailable("pyrender")
    ctx = Ctx(tmp_path)
    argv = ["render", str(ctx.scene_file()), "-b", "pyrender", "-s", "1", "--outputs", outputs]
    proc = subprocess.run(
        [sys.executable, "-m", "blendify_core", *argv, "-o", str(ctx.out / f"r{suffix}")],
        capture_output=True,
        text=True,
        timeout=CLI_TIMEOUT,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert _listing(ctx.out) == files


def test_render_many_reports_a_corrupt_scene_job_as_failed(tmp_path):
    """A batch job whose scene file is corrupt fails with the reason (naming the file), the run goes on,
    and no output file is written."""
    ctx = Ctx(tmp_path)
    bad = ctx.file("bad.npz", os.urandom(300))
    jobs = [bf.RenderJob(bad, ctx.out / "a.png", backend="pyrender", samples=1)]
    report = bf.render_many(jobs, workers=1, progress=False, manifest=False)
    assert not report.ok
    (status,) = report.jobs
    assert status.status == "failed" and "bad.npz" in status.reason, status.reason
    assert _listing(ctx.out) == []
