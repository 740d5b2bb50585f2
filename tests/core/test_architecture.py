"""The layout's promises (docs/architecture.md): no import circles between modules or packages, each layer
imports only the layers below it, backends read parameters as attributes, every backend translates every IR
type with the same module names."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
CORE = ROOT / "blendify_core"
BACKENDS = {"blender": "blendify_blender", "mitsuba": "blendify_mitsuba", "pyrender": "blendify_pyrender"}

#: the layers, bottom first; a module may import its own layer and the layers before it
LAYERS = [
    {"blendify_core.errors", "blendify_core.registry", "blendify_core._memo", "blendify_core.typing"},
    {"blendify_core.io"},
    {"blendify_core.ir"},
    {"blendify_core.pipeline"},
    {"blendify_core.evaluate", "blendify_core.batch", "blendify_core.testing"},
    {"blendify_core.utils", "blendify_core.export"},
    {"blendify_core.cli", "blendify_core", "blendify_core.__main__"},
]


def _modules(package_dir: Path, package: str) -> dict[str, Path]:
    out = {}
    for f in package_dir.rglob("*.py"):
        rel = f.relative_to(package_dir).with_suffix("")
        name = ".".join((package, *rel.parts)).removesuffix(".__init__")
        out[name] = f
    return out


def _edges(mods: dict[str, Path]) -> dict[str, set[str]]:
    """Module-level imports between the given modules (TYPE_CHECKING blocks and function bodies excluded)."""
    edges: dict[str, set[str]] = {m: set() for m in mods}
    for m, f in mods.items():
        for node in ast.parse(f.read_text()).body:
            if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                for a in node.names:
                    full = f"{node.module}.{a.name}"
                    if full in mods:
                        edges[m].add(full)
                    elif node.module in mods:
                        edges[m].add(node.module)
            elif isinstance(node, ast.Import):
                edges[m].update(a.name for a in node.names if a.name in mods)
        edges[m].discard(m)
    return edges


def _cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    found: list[list[str]] = []
    counter = [0]

    def visit(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in edges.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                found.append(sorted(comp))

    for v in list(edges):
        if v not in index:
            visit(v)
    return found


def _package(module: str, depth: int) -> str:
    return ".".join(module.split(".")[:depth])


@pytest.mark.parametrize(
    ("package_dir", "package", "depth"),
    [(CORE, "blendify_core", 2)] + [(ROOT / "backends" / d / p, p, 2) for d, p in BACKENDS.items()],
    ids=["blendify_core", *BACKENDS],
)
def test_no_import_circles(package_dir, package, depth):
    edges = _edges(_modules(package_dir, package))
    assert _cycles(edges) == [], "module import circles"
    packages: dict[str, set[str]] = {}
    for m, targets in edges.items():
        for t in targets:
            a, b = _package(m, depth), _package(t, depth)
            if a != b:
                packages.setdefault(a, set()).add(b)
    assert _cycles(packages) == [], "package import circles"


def test_each_layer_imports_only_the_layers_below():
    edges = _edges(_modules(CORE, "blendify_core"))

    def layer(module: str) -> int:
        for i, members in enumerate(LAYERS):
            if any(module == p or module.startswith(p + ".") for p in members if p != "blendify_core"):
                return i
        return len(LAYERS) - 1  # the package __init__ is the top

    wrong = [
        f"{m} (layer {layer(m)}) imports {t} (layer {layer(t)})"
        for m, ts in edges.items()
        for t in ts
        if layer(t) > layer(m)
    ]
    assert wrong == []


def test_the_architecture_doc_names_every_core_package():
    doc = (ROOT / "docs" / "architecture.md").read_text()
    for sub in ("ir/", "io/", "pipeline/", "evaluate/", "batch/", "utils/", "export/", "cli/", "registry.py"):
        assert sub in doc, sub
    assert "http" not in doc, "docs/architecture.md is self-contained (no links outside the repository)"


@pytest.mark.parametrize("backend", list(BACKENDS))
def test_backends_share_the_module_names_and_read_attributes(backend):
    from blendify_core.ir.types import IR_TYPES

    pkg = ROOT / "backends" / backend / BACKENDS[backend]
    for name in ("translate.py", "render.py", "capabilities.py", "session.py"):
        assert (pkg / name).is_file(), f"{backend}: {name}"
    kinds = sorted({k for t in IR_TYPES if isinstance(k := getattr(t, "kind", None), str)})
    branch = re.compile(r"\.kind\s*[!=]=\s*[\"'](" + "|".join(map(re.escape, kinds)) + r")[\"']")
    offenders = [
        f"{f.relative_to(ROOT)}:{n}"
        for f in pkg.rglob("*.py")
        for n, line in enumerate(f.read_text().splitlines(), 1)
        if ".parameters()" in line or branch.search(line)
    ]
    assert offenders == [], "backends read IR parameters as attributes and dispatch on types"
