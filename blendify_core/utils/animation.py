"""``bf.render_frames``: render a sequence (camera path or per-frame scene updates) to PNG frames and/or
an MP4, with a progress bar, backend reuse between frames, and resumption of interrupted runs."""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from blendify_core.errors import BackendUnavailableError, InvalidSceneError
from blendify_core.errors import describe as _describe
from blendify_core.io.output import AtomicOutput, atomic_write, ensure_folder, output_error
from blendify_core.ir.scene import Scene
from blendify_core.ir.validate import as_bool, as_float, strict_api, strict_arguments
from blendify_core.pipeline.backend import Backend
from blendify_core.pipeline.render import choose_backend
from blendify_core.pipeline.render import render as bf_render
from blendify_core.pipeline.result import RenderResult
from blendify_core.pipeline.result import _jsonable as core_jsonable
from blendify_core.registry import get_backend_class
from blendify_core.typing import Float64Array, UInt8Array
from blendify_core.utils.image import _color3, blend_with_background, to_display_uint8
from blendify_core.utils.trajectory import Pose, Trajectory, apply_pose

__all__ = ["render_frames", "FramesReport", "MANIFEST_NAME", "write_video"]

MANIFEST_NAME = "frames_manifest.jsonl"
_MANIFEST_VERSION = 1


@strict_api
@dataclass
class FramesReport:
    """What :func:`render_frames` did.

    ``frames``: PNG paths (one per frame, when ``frames_dir`` was given); ``video``: the MP4 path or
    None; ``rendered`` / ``skipped``: frame indices rendered now / reused from an earlier run;
    ``seconds``: render time per rendered frame; ``results``: the RenderResults when kept
    (``keep_results=True``, or when neither frames_dir nor video_path was given)."""

    frames: list[Path] = field(default_factory=list)
    video: Path | None = None
    rendered: list[int] = field(default_factory=list)
    skipped: list[int] = field(default_factory=list)
    seconds: list[float] = field(default_factory=list)
    results: list[RenderResult] = field(default_factory=list)
    backend: str | None = None

    def __len__(self) -> int:
        return len(self.rendered) + len(self.skipped)


def _jsonable(value: object) -> object:
    return core_jsonable(value)


def _read_manifest(path: Path) -> dict[str, dict[str, Any]]:
    """Frame key -> entry from the JSON-lines manifest (the last entry of a frame wins; a line cut short
    by a crash, or any malformed line, is ignored)."""
    entries: dict[str, dict[str, Any]] = {}
    try:
        lines = path.read_text().splitlines()
    except OSError:
        return entries
    for line in lines:
        try:
            entry = json.loads(line)
        except ValueError:
            continue
        if (
            isinstance(entry, dict)
            and entry.get("version") == _MANIFEST_VERSION
            and isinstance(entry.get("frame"), str)
        ):
            entries[entry["frame"]] = entry
    return entries


def _rewrite_manifest(path: Path, entries: dict[str, dict[str, Any]]) -> None:
    """Replace the manifest by one line per frame (atomically): keeps it compact across resumed runs."""
    text = "".join(json.dumps(entries[k], sort_keys=True) + "\n" for k in sorted(entries))

    def writer(tmp: str) -> None:
        with open(tmp, "w") as f:
            f.write(text)

    atomic_write(path, writer, arg="frames_dir")


def _append_manifest(path: Path, entry: dict[str, Any]) -> None:
    """Append one finished frame (O(1) per frame, durable before the next frame starts)."""
    try:
        with open(path, "a") as f:  # a plain open: a new manifest gets the usual mode (0o666 & ~umask)
            f.write(json.dumps(entry, sort_keys=True) + "\n")
            f.flush()
            os.fsync(f.fileno())
    except OSError as exc:
        raise output_error("frames_dir", path, exc) from exc


def _even_rgb(frame: np.ndarray) -> np.ndarray:
    """Pad an (H, W, 3) uint8 frame to even dimensions (H.264 4:2:0 needs them) by edge replication."""
    h, w = frame.shape[:2]
    if h % 2 or w % 2:
        frame = np.pad(frame, ((0, h % 2), (0, w % 2), (0, 0)), mode="edge")
    return frame


def _video_frame(result_or_png: str | Path | RenderResult, background: Float64Array) -> UInt8Array:
    if isinstance(result_or_png, (str, Path)):
        from PIL import Image

        with Image.open(result_or_png) as im:
            arr = np.asarray(im.convert("RGBA"))
        rgb = blend_with_background(arr, background)
    else:
        rgb = blend_with_background(result_or_png.to_srgb8(), background)
    return _even_rgb(rgb)


class _VideoWriter:
    """Writes frames to a temporary file next to ``path`` (the mode of a plain ``open``, see
    :mod:`blendify_core.io.output`); :meth:`finish` renames it into place, :meth:`abort` removes it."""

    def __init__(self, path: Path, fps: float, quality: float | None, codec: str) -> None:
        try:
            import imageio.v2 as imageio
            import imageio_ffmpeg  # noqa: F401  (the packaged ffmpeg binary)
        except ImportError:
            raise BackendUnavailableError(
                "video_path: writing an MP4 needs the 'video' extra: pip install 'blendify-core[video]' "
                "(imageio and imageio-ffmpeg)"
            ) from None
        # checks the folder, the name and the permissions before any frame is rendered
        self._out = AtomicOutput(path, arg="video_path", suffix=path.suffix or ".mp4")
        self.tmp = self._out.tmp
        self.path = path
        kwargs: dict[str, Any] = {"fps": fps, "codec": codec, "macro_block_size": 1, "pixelformat": "yuv420p"}
        if quality is not None:
            kwargs["quality"] = quality
        try:
            self._writer = imageio.get_writer(str(self.tmp), format="FFMPEG", mode="I", **kwargs)
        except BaseException:
            self._out.discard()
            raise
        self.shape: tuple[int, ...] | None = None

    def append(self, frame: np.ndarray) -> None:
        if self.shape is None:
            self.shape = frame.shape
        elif frame.shape != self.shape:
            raise InvalidSceneError(
                f"video_path: every frame of a video must have the same size; frame of shape {frame.shape} "
                f"after frames of shape {self.shape} (did the camera resolution change?)"
            )
        self._writer.append_data(frame)

    def finish(self) -> Path:
        try:
            self._writer.close()
        except BaseException as exc:
            self._out.discard()
            if isinstance(exc, OSError):
                raise output_error("video_path", self.path, exc) from exc
            raise
        return self._out.commit()

    def abort(self) -> None:
        try:
            self._writer.close()
        except Exception:  # noqa: BLE001 - the original error matters more
            pass
        self._out.discard()


@strict_arguments
def write_video(
    frames: Sequence[str | Path | RenderResult | ArrayLike],
    video_path: str | os.PathLike[str],
    fps: float = 30.0,
    background: ArrayLike = (1.0, 1.0, 1.0),
    quality: float | None = 8.0,
    codec: str = "libx264",
) -> Path:
    """Encode PNG paths, uint8 images or RenderResults into an MP4 (H.264, yuv420p), atomically.
    Transparent pixels are composited over ``background`` (sRGB); odd sizes are padded to even."""
    bg = _color3("background", background)
    fps = as_float("fps", fps, min_value=0.0, exclusive_min=True)
    if len(frames) == 0:
        raise InvalidSceneError("frames: expected at least one frame")
    writer = _VideoWriter(Path(video_path), fps, quality, codec)
    try:
        for f in frames:
            if isinstance(f, (str, Path, RenderResult)):
                writer.append(_video_frame(f, bg))
            else:
                img = to_display_uint8(f)
                writer.append(_even_rgb(blend_with_background(img, bg) if img.shape[2] == 4 else img))
        return writer.finish()
    except BaseException:
        writer.abort()
        raise


#: what ``render_frames`` accepts as the sequence: a trajectory, a list of poses, or a per-frame callback
FrameSource = Trajectory | Sequence[Pose | dict[str, Any]] | Callable[[Scene, int], object]


def _frame_plan(
    trajectory_or_callback: FrameSource, fps: float, n_frames: int | None, interpolation: str, smoothness: float
) -> tuple[list[Pose | dict[str, Any]] | None, Callable[[Scene, int], object] | None, int]:
    """(poses, None, count) for a trajectory or a list of poses; (None, callback, count) for a callback."""
    if isinstance(trajectory_or_callback, Trajectory):
        poses: list[Pose | dict[str, Any]] = list(
            trajectory_or_callback.refine(1.0 / fps, interpolation=interpolation, smoothness=smoothness)
        )
        if n_frames is not None:
            poses = poses[:n_frames]
        return poses, None, len(poses)
    if isinstance(trajectory_or_callback, (list, tuple)) and all(
        isinstance(p, (Pose, dict)) for p in trajectory_or_callback
    ):
        poses = list(trajectory_or_callback)
        if n_frames is not None:
            poses = poses[:n_frames]
        return poses, None, len(poses)
    if callable(trajectory_or_callback):
        if n_frames is None or isinstance(n_frames, bool) or not isinstance(n_frames, (int, np.integer)):
            raise InvalidSceneError(
                f"n_frames: a per-frame callback needs the number of frames (a positive integer), got {n_frames!r}"
            )
        return None, trajectory_or_callback, int(n_frames)
    raise InvalidSceneError(
        "trajectory_or_callback: expected a Trajectory, a list of poses, or a callable "
        f"callback(scene, frame_index), got {_describe(trajectory_or_callback)}"
    )


@strict_arguments
def render_frames(
    scene: Scene,
    trajectory_or_callback: FrameSource,
    backend: str | Backend | None = None,
    quality: str = "final",
    frames_dir: str | os.PathLike[str] | None = None,
    video_path: str | os.PathLike[str] | None = None,
    fps: float = 30.0,
    resume: bool = True,
    progress: bool = True,
    n_frames: int | None = None,
    interpolation: str = "cubic",
    smoothness: float = 0.0,
    background: ArrayLike = (1.0, 1.0, 1.0),
    video_quality: float | None = 8.0,
    keep_results: bool = False,
    restore_camera: bool = True,
    on_frame: Callable[[Scene, int], object] | None = None,
    **render_kwargs: Any,
) -> FramesReport:
    """Render a sequence of frames of ``scene`` with :func:`blendify_core.pipeline.render`.

    ``trajectory_or_callback``:
      - a :class:`~blendify_core.utils.Trajectory`: refined every ``1 / fps`` seconds (``interpolation``,
        ``smoothness``, see :meth:`Trajectory.refine`) and applied to ``scene.camera`` per frame;
      - a list of poses (e.g. ``trajectory.refine(...)``);
      - a callable ``callback(scene, frame_index)`` that updates any IR object (move a mesh, recolour a
        point cloud, change a light) for frame ``frame_index`` in ``range(n_frames)``; it is called for
        every frame in order, including frames skipped on resume.

    ``on_frame(scene, frame_index)``: called after the camera pose of a trajectory frame is applied, to
    update other objects for that view (e.g. recolour a point cloud with
    :func:`approximate_colors_from_camera` for the new camera).

    Output: ``frames_dir`` gets ``frame_00000.png``... (8-bit sRGB, straight alpha, written atomically;
    other requested ``outputs`` as ``depth_00000.png`` etc.) and a ``frames_manifest.jsonl`` recording each
    frame's provenance (scene fingerprint + settings); ``video_path`` gets an H.264 MP4 (needs the
    ``video`` extra: imageio + imageio-ffmpeg) with transparent pixels over ``background``.
    With neither, the RenderResults are returned in the report.

    ``resume=True`` (with ``frames_dir``): a frame whose PNG exists and whose manifest entry matches the
    current scene fingerprint and settings is not rendered again, so an interrupted run continues where it
    stopped, and changing the scene or settings re-renders only the frames that changed.

    The backend instance is resolved once and reused for every frame (``bf.render``'s shared instance),
    so backends that cache the translated scene only update what changed. ``progress=True`` shows a
    tqdm progress bar with ETA. The camera pose is restored afterwards (``restore_camera``).
    Remaining keyword arguments go to :func:`blendify_core.pipeline.render` (``samples``, ``outputs``, ``seed``,
    backend options...).
    """
    if not isinstance(scene, Scene):
        raise InvalidSceneError(f"scene: expected a blendify_core.Scene, got {_describe(scene)}")
    fps = as_float("fps", fps, min_value=0.0, exclusive_min=True)
    poses, callback, count = _checked_plan(trajectory_or_callback, fps, n_frames, interpolation, smoothness)
    resume, progress = as_bool("resume", resume), as_bool("progress", progress)
    keep_results, restore_camera = as_bool("keep_results", keep_results), as_bool("restore_camera", restore_camera)
    if on_frame is not None and not callable(on_frame):
        raise InvalidSceneError(
            f"on_frame: expected a callable on_frame(scene, frame_index), got {_describe(on_frame)}"
        )
    if poses is not None and scene.camera is None:
        raise InvalidSceneError("scene.camera: a trajectory moves the scene camera; set a camera first")
    bg = _color3("background", background)
    backend_name, backend_arg = _resolve_backend(backend, quality)
    outputs = _requested_outputs(render_kwargs, video_path)
    settings_key = _settings_key(backend, backend_name, quality, render_kwargs)
    store = _FrameStore.open(frames_dir, resume, settings_key)
    keep = keep_results or (store.folder is None and video_path is None)

    report = FramesReport(backend=backend_name)
    cam = scene.camera
    saved_pose = None if cam is None else (cam.quaternion.copy(), cam.translation.copy())
    writer = _VideoWriter(Path(video_path), fps, video_quality, "libx264") if video_path is not None else None
    frames = _FrameRenderer(scene, backend_arg, quality, render_kwargs, outputs, store, writer, bg, keep, report)
    try:
        _run_frames(frames, poses, callback, on_frame, count, progress)
        if writer is not None:
            report.video = writer.finish()
            writer = None
    finally:
        if writer is not None:
            writer.abort()
        if restore_camera and poses is not None and saved_pose is not None and cam is not None and scene.camera is cam:
            cam.set_position(rotation_mode="quaternionWXYZ", rotation=saved_pose[0], translation=saved_pose[1])
    return report


def _run_frames(
    frames: _FrameRenderer,
    poses: list[Pose | dict[str, Any]] | None,
    callback: Callable[[Scene, int], object] | None,
    on_frame: Callable[[Scene, int], object] | None,
    count: int,
    progress: bool,
) -> None:
    """Pose (or update) the scene for each frame in order, then render or reuse it, with a progress bar."""
    scene, report = frames.scene, frames.report
    bar = _progress_bar(count) if progress else None
    try:
        for i in range(count):
            if poses is not None:
                if scene.camera is None:
                    raise InvalidSceneError(f"scene.camera: removed before frame {i}; a trajectory moves the camera")
                apply_pose(scene.camera, poses[i])
            elif callback is not None:
                callback(scene, i)
            if on_frame is not None:
                on_frame(scene, i)
            frames.frame(i)
            if bar is not None:
                bar.set_postfix(rendered=len(report.rendered), skipped=len(report.skipped), refresh=False)
                bar.update(1)
    finally:
        if bar is not None:
            bar.close()


def _checked_plan(
    trajectory_or_callback: FrameSource,
    fps: float,
    n_frames: int | None,
    interpolation: str,
    smoothness: float,
) -> tuple[list[Pose | dict[str, Any]] | None, Callable[[Scene, int], object] | None, int]:
    """:func:`_frame_plan` after checking ``n_frames``."""
    if n_frames is not None and (
        isinstance(n_frames, bool) or not isinstance(n_frames, (int, np.integer)) or n_frames < 1
    ):
        raise InvalidSceneError(f"n_frames: expected a positive integer, got {n_frames!r}")
    return _frame_plan(trajectory_or_callback, fps, n_frames, interpolation, smoothness)


def _resolve_backend(backend: object, quality: str) -> tuple[str, str | Backend]:
    """The backend's name and what to pass to bf.render, resolved once (a name stays a name so bf.render
    reuses its shared instance)."""
    if backend is None:
        name, _notes = choose_backend(quality)
        return name, name
    if isinstance(backend, Backend):
        return backend.name, backend
    if isinstance(backend, str):
        return backend, backend
    raise InvalidSceneError(f"backend: expected a backend name or instance, got {_describe(backend)}")


def _requested_outputs(render_kwargs: dict[str, Any], video_path: object) -> tuple[str, ...]:
    """The outputs to write (``rgba`` spelled ``rgb``); a video needs ``rgb``."""
    outputs = render_kwargs.get("outputs", ("rgb",))
    outputs = (outputs,) if isinstance(outputs, str) else tuple(outputs)
    outputs = tuple("rgb" if o == "rgba" else o for o in outputs)
    if video_path is not None and "rgb" not in outputs:
        raise InvalidSceneError("video_path: a video needs the 'rgb' output; add 'rgb' to outputs")
    return outputs


def _settings_key(backend: object, backend_name: str, quality: str, render_kwargs: dict[str, Any]) -> object:
    """What decides a frame besides the scene (a manifest entry must match it to be reused)."""
    engine_version = backend.engine_version() if isinstance(backend, Backend) else None
    if engine_version is None and not isinstance(backend, Backend):
        engine_version = get_backend_class(backend_name).engine_version()
    return _jsonable(
        {
            "backend": backend_name,
            "engine_version": engine_version,
            "quality": quality,
            "render_kwargs": {k: render_kwargs[k] for k in sorted(render_kwargs)},
        }
    )


def _progress_bar(count: int) -> Any:
    from tqdm.auto import tqdm

    return tqdm(total=count, unit="frame", desc="render_frames", dynamic_ncols=True)


@dataclass
class _FrameStore:
    """The frames folder and its manifest (frame key -> entry of the frame rendered there earlier)."""

    folder: Path | None
    manifest_path: Path | None
    manifest: dict[str, dict[str, Any]]
    settings_key: object
    resume: bool

    @classmethod
    def open(cls, frames_dir: str | os.PathLike[str] | None, resume: bool, settings_key: object) -> _FrameStore:
        if frames_dir is None:
            return cls(None, None, {}, settings_key, resume)
        folder = ensure_folder(frames_dir, arg="frames_dir")
        manifest_path = folder / MANIFEST_NAME
        manifest = _read_manifest(manifest_path) if resume else {}
        if manifest_path.exists():
            _rewrite_manifest(manifest_path, manifest)
        return cls(folder, manifest_path, manifest, settings_key, resume)

    def is_done(self, i: int, names: dict[str, str], fingerprint: str) -> bool:
        """True when frame ``i`` was rendered from the same scene and settings and its files exist."""
        if self.folder is None:
            return False
        entry = self.manifest.get(f"{i:05d}")
        folder = self.folder
        return (
            self.resume
            and isinstance(entry, dict)
            and entry.get("fingerprint") == fingerprint
            and entry.get("settings") == self.settings_key
            and all((folder / n).is_file() for n in names.values())
        )

    def save(
        self, i: int, names: dict[str, str], fingerprint: str | None, seconds: float, result: RenderResult
    ) -> None:
        """Write frame ``i``'s files and append its manifest entry."""
        if self.folder is None or self.manifest_path is None:
            return
        for o, n in names.items():
            result.save(self.folder / n, output=o)
        entry: dict[str, Any] = {
            "version": _MANIFEST_VERSION,
            "frame": f"{i:05d}",
            "fingerprint": fingerprint,
            "settings": self.settings_key,
            "files": sorted(names.values()),
            "seconds": seconds,
            "backend": result.meta.get("backend"),
            "engine_version": result.meta.get("engine_version"),
        }
        self.manifest[f"{i:05d}"] = entry
        _append_manifest(self.manifest_path, entry)


@dataclass
class _FrameRenderer:
    """Renders (or reuses) one frame at a time into the store, the video and the report."""

    scene: Scene
    backend: str | Backend
    quality: str
    render_kwargs: dict[str, Any]
    outputs: tuple[str, ...]
    store: _FrameStore
    writer: _VideoWriter | None
    background: Float64Array
    keep: bool
    report: FramesReport

    def frame(self, i: int) -> None:
        names = {o: (f"frame_{i:05d}.png" if o == "rgb" else f"{o}_{i:05d}.png") for o in self.outputs}
        store, report = self.store, self.report
        fingerprint = self.scene.fingerprint() if store.folder is not None else None
        if store.folder is not None and fingerprint is not None and store.is_done(i, names, fingerprint):
            report.skipped.append(i)
            if self.writer is not None:
                self.writer.append(_video_frame(store.folder / names["rgb"], self.background))
        else:
            t0 = time.perf_counter()
            result = bf_render(self.scene, backend=self.backend, quality=self.quality, **self.render_kwargs)
            report.seconds.append(time.perf_counter() - t0)
            report.rendered.append(i)
            store.save(i, names, fingerprint, report.seconds[-1], result)
            if self.writer is not None:
                self.writer.append(_video_frame(result, self.background))
            if self.keep:
                report.results.append(result)
        if store.folder is not None:
            report.frames.append(store.folder / names.get("rgb", next(iter(names.values()))))
