"""The ``blendify`` command line: ``info``, ``render``, ``demo``, ``batch``, ``crosscheck``, ``export``, ``show``.

Every command has ``--help``; every error is one line ``blendify <command>: error: ...`` on stderr, and
every command exits with the codes of :data:`blendify_core.errors.EXIT_CODES` (0 success, 1 the work
failed, 2 bad usage or input, 3 backend unavailable, 130 interrupted).
"""

from __future__ import annotations

import argparse
import logging
import platform
import sys
from pathlib import Path
from typing import Any, NoReturn

from blendify_core import __version__
from blendify_core.batch.jobs import read_jobs
from blendify_core.batch.local import DEFAULT_RECYCLE_AFTER
from blendify_core.batch.run import render_many
from blendify_core.batch.worker import save_outputs
from blendify_core.cli.demo import run_demo
from blendify_core.errors import BlendifyError, InvalidSceneError, exit_code, exit_code_epilog
from blendify_core.evaluate.crosscheck import crosscheck_main
from blendify_core.ir.scene import Scene
from blendify_core.pipeline.cost import estimate_cost
from blendify_core.pipeline.render import render
from blendify_core.pipeline.settings import QUALITIES
from blendify_core.registry import available_backends, backend_names, get_backend_class

__all__ = ["main"]


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:
        # one line, no usage dump, exit code 2 (argparse's convention)
        self.exit(2, f"{self.prog}: error: {message}\n")


def _info(args: argparse.Namespace) -> int:
    print(f"blendify-core {__version__} (Python {platform.python_version()}, {platform.system()} {platform.machine()})")
    import numpy
    import scipy

    print(f"numpy {numpy.__version__}, scipy {scipy.__version__}")
    for name, st in available_backends().items():
        state = "available" if st.available else "unavailable"
        version = f" (engine {st.version})" if st.version else ""
        reason = f": {st.reason}" if st.reason else ""
        print(f"  {name:<10} {state}{version}{reason}")
        # optional per-backend details (e.g. mitsuba: the variant chosen here and its probes)
        details = getattr(get_backend_class(name), "info_details", None) if st.available else None
        for line in details() if details is not None else ():
            print(f"  {'':<10} {line}")
    return 0


def _outputs(text: str) -> tuple[str, ...]:
    return tuple(t.strip() for t in text.split(",") if t.strip())


def _render(args: argparse.Namespace) -> int:
    # check where the image goes before rendering, not after a long render
    target = Path(args.output)
    if target.suffix.lower() not in (".png", ".exr", ".npz"):
        raise InvalidSceneError(f"--output: expected a .png, .exr or .npz file name, got {args.output!r}")
    if not target.absolute().parent.is_dir():
        raise InvalidSceneError(f"--output: the folder {str(target.absolute().parent)!r} does not exist")
    scene = Scene.load(args.scene, allow_outside=args.allow_outside)
    overrides: dict[str, Any] = {} if args.target_error is None else {"target_error": args.target_error}
    if args.device is not None:
        overrides["device"] = args.device
    if args.estimate:
        if args.samples is not None:
            raise InvalidSceneError("--estimate: the pilot chooses the samples; drop --samples")
        est = estimate_cost(scene, backend=args.backend, quality=args.quality, seed=args.seed, **overrides)
        print(est)
        return 0
    result = render(
        scene,
        backend=args.backend,
        quality=args.quality,
        samples=args.samples,
        seed=args.seed,
        outputs=_outputs(args.outputs),
        strict=args.strict,
        **overrides,
    )
    # the same files as a batch job: OUT = rgb (or the first output), OUT.<name>.<ext> for the others
    out = Path(args.output)
    save_outputs(result, str(out), tuple(result.meta["settings"]["outputs"]))
    t = result.meta.get("timings", {}).get("total", 0.0)
    err = result.meta.get("estimated_error")
    accuracy = "" if err is None else f", {result.meta['samples']} samples, estimated error {err:.3g}"
    print(f"wrote {out} ({result.meta['backend']}, {t:.2f} s{accuracy})")
    return 0


def _demo(args: argparse.Namespace) -> int:
    run_demo(args.output, backend=args.backend, quality=args.quality, size=args.size, samples=args.samples)
    return 0


def _export(args: argparse.Namespace) -> int:
    scene = Scene.load(args.scene, allow_outside=args.allow_outside)
    print(f"wrote {scene.export(args.output)}")
    return 0


def _show(args: argparse.Namespace) -> int:
    scene = Scene.load(args.scene, allow_outside=args.allow_outside)
    view = scene.show(viewer=args.viewer, path=args.output, open_browser=False if args.no_browser else None)
    path = getattr(view, "path", None)
    if path is not None:
        print(f"wrote {path}")
    return 0


def _crosscheck(args: argparse.Namespace) -> int:  # reached only through main()'s own dispatch
    return int(crosscheck_main(args.rest, parser_class=_Parser) or 0)


def _batch(args: argparse.Namespace) -> int:
    jobs = read_jobs(args.jobs)
    report = render_many(
        jobs,
        executor=args.executor,
        workers=args.workers,
        recycle_after=args.recycle if args.recycle > 0 else None,
        timeout=args.timeout,
        progress=not args.no_progress,
        manifest=args.manifest,
    )
    print(report.summary())
    return 0 if report.ok else 1  # any failed job, even with others done, exits 1 (documented in --help)


def _backend_argument(p: argparse.ArgumentParser) -> None:
    names = backend_names()
    p.add_argument(
        "-b",
        "--backend",
        default=None,
        choices=names,
        metavar="BACKEND",
        help=f"one of: {', '.join(names)} (default: the best available for the quality)",
    )


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="blendify",
        description="blendify-core: one numpy scene, three renderers.",
        epilog=exit_code_epilog(),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"blendify-core {__version__}")
    parser.add_argument("-v", "--verbose", action="store_true", help="log backend choices and engine messages")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    common: dict[str, Any] = {"epilog": exit_code_epilog(), "formatter_class": argparse.RawDescriptionHelpFormatter}

    p = sub.add_parser("info", help="versions, available backends and why others are not", **common)
    p.set_defaults(func=_info)

    p = sub.add_parser("render", help="render a scene file (.npz) to an image", **common)
    p.add_argument("scene", help="scene file written by Scene.save()")
    _backend_argument(p)
    p.add_argument("-q", "--quality", default="final", choices=QUALITIES)
    p.add_argument("-o", "--output", default="render.png", help="output file: .png, .exr or .npz")
    p.add_argument("-s", "--samples", type=int, default=None, help="samples per pixel (overrides the preset)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--outputs", default="rgb", help="comma-separated: rgb,depth,normal,albedo,instance")
    p.add_argument("--allow-outside", action="store_true", help="allow texture paths outside the scene's folder")
    p.add_argument(
        "--target-error", type=float, default=None, help="render passes until this relative RMS error (final: 0.01)"
    )
    p.add_argument(
        "--estimate", action="store_true", help="print the predicted samples and time from a short pilot; no render"
    )
    p.add_argument(
        "--device",
        default=None,
        help="cpu, gpu, or the engine's own device (cycles: OPTIX, CUDA, HIP, METAL, ONEAPI; mitsuba: cuda, llvm, "
        "scalar); default: the backend's",
    )
    p.add_argument(
        "--strict",
        action="store_true",
        help="refuse approximations and a missing device (exit 1 / 3) instead of warning",
    )
    p.set_defaults(func=_render)

    p = sub.add_parser("demo", help="render the built-in donut demo into a labelled contact sheet", **common)
    p.add_argument("-o", "--output", default="blendify_demo.png")
    _backend_argument(p)
    p.add_argument("-q", "--quality", default="draft", choices=QUALITIES)
    p.add_argument("--size", type=int, default=256, help="panel size in pixels")
    p.add_argument("-s", "--samples", type=int, default=None)
    p.set_defaults(func=_demo)

    p = sub.add_parser(
        "batch",
        help="render many scene files listed in a JSON-lines file, resumably",
        description="Render many scene files listed in a JSON-lines file, resumably (run it again to skip "
        "finished jobs and retry failed ones).",
        epilog="any failed job, even with others done, exits 1 (the summary lists each reason).\n\n"
        + exit_code_epilog(),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("jobs", help='JSON lines: {"scene": "a.npz", "output": "a.png", "backend": ..., "samples": ...}')
    p.add_argument("--executor", default="local", help="local (process pool), ray, or ray:ADDRESS")
    p.add_argument("-w", "--workers", type=int, default=None, help="parallel jobs (default: one per core)")
    p.add_argument("--recycle", type=int, default=DEFAULT_RECYCLE_AFTER, help="jobs per worker process; 0 = never")
    p.add_argument("--timeout", type=float, default=None, help="seconds per job before it is killed and failed")
    p.add_argument("--manifest", default=None, help="manifest file (default: blendify_manifest.jsonl by the outputs)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=_batch)

    p = sub.add_parser(
        "export",
        help="write a scene file (.npz) as glTF (.glb/.gltf), a Mitsuba scene (.xml), a viewer page (.html) or .blend",
        **common,
    )
    p.add_argument("scene", help="scene file written by Scene.save()")
    p.add_argument("output", help="output file; its suffix picks the format: .glb, .gltf, .xml, .html, .blend")
    p.add_argument("--allow-outside", action="store_true", help="allow texture paths outside the scene's folder")
    p.set_defaults(func=_export)

    p = sub.add_parser("show", help="look at a scene file: pyrender's viewer, or an offline HTML page", **common)
    p.add_argument("scene", help="scene file written by Scene.save()")
    p.add_argument("--viewer", default="auto", choices=("auto", "pyrender", "html"))
    p.add_argument("-o", "--output", default=None, help="where the HTML page goes (default: the temporary folder)")
    p.add_argument("--no-browser", action="store_true", help="write the HTML page without opening a browser")
    p.add_argument("--allow-outside", action="store_true", help="allow texture paths outside the scene's folder")
    p.set_defaults(func=_show)

    p = sub.add_parser("crosscheck", help="render a scene with every backend and compare them pairwise", add_help=False)
    p.add_argument("rest", nargs=argparse.REMAINDER)
    p.set_defaults(func=_crosscheck)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``blendify`` command; returns the process exit code."""
    parser = build_parser()
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] == "crosscheck":  # its own parser: options may come before the scene path
        try:
            return int(crosscheck_main(argv[1:], parser_class=_Parser) or 0)
        except KeyboardInterrupt:
            print("blendify crosscheck: interrupted", file=sys.stderr)
            return 130
    args, unknown = parser.parse_known_args(argv)
    if unknown:  # named by the subcommand, as its other errors are
        where = f"blendify {args.command}" if getattr(args, "command", None) else "blendify"
        print(f"{where}: error: unrecognized arguments: {' '.join(unknown)}", file=sys.stderr)
        return 2
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING, format="%(message)s")
    if not getattr(args, "command", None):
        parser.print_help()
        return 2
    for name in ("samples", "size"):
        value = getattr(args, name, None)
        if value is not None and value < 1:
            print(f"blendify {args.command}: error: --{name} must be >= 1, got {value}", file=sys.stderr)
            return 2
    try:
        return int(args.func(args))
    except KeyboardInterrupt:
        print(f"blendify {args.command}: interrupted", file=sys.stderr)
        return 130
    except (BlendifyError, OSError) as exc:
        print(f"blendify {args.command}: error: {exc}", file=sys.stderr)
        return exit_code(exc)


def _entry() -> NoReturn:  # pragma: no cover - used by `python -m blendify_core`
    raise SystemExit(main())
