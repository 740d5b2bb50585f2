"""Shared command-line options of the examples: every example runs in under a minute at its defaults."""

from __future__ import annotations

import argparse
from pathlib import Path


def parser(description: str, size: int = 256, samples: int = 32) -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(description=description)
    p.add_argument("-o", "--out", default="out", help="output folder (created)")
    p.add_argument("-b", "--backend", default=None, help="cycles, mitsuba or pyrender (default: best available)")
    p.add_argument("--size", type=int, default=size, help="image width in pixels")
    p.add_argument("--samples", type=int, default=samples, help="samples per pixel for path tracers")
    return p


def out_dir(args: argparse.Namespace) -> Path:
    d = Path(args.out)
    d.mkdir(parents=True, exist_ok=True)
    return d


def data_file(name: str) -> Path:
    """A file of the repository's test data (tests/data, sources and licences in its README)."""
    from blendify_core.testing import data_path

    return data_path(name)
