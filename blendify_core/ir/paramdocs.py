"""``docs/parameters.md``, rendered from the parameter declarations of every material and light.

``python -m blendify_core.ir.paramdocs [PATH]`` rewrites the file (default ``docs/parameters.md``);
``tests/core/test_core_params.py`` checks that the committed file is current.
"""

from __future__ import annotations

import sys
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

from blendify_core.ir.lights import (
    AreaLight,
    BackgroundLight,
    EnvironmentMap,
    PointLight,
    SpotLight,
    SunLight,
)
from blendify_core.ir.materials import (
    MATERIAL_COLOR_SPACE,
    DiffuseMaterial,
    GlossyBSDFMaterial,
    Material,
    MetalMaterial,
    MetalWireframeMaterial,
    PlasticMaterial,
    PlasticWireframeMaterial,
    PrincipledBSDFMaterial,
    PrincipledBSDFWireframeMaterial,
)
from blendify_core.ir.params import POSE, REQUIRED, TAG, Declared, Param

__all__ = ["parameters_markdown", "main"]

_SHARED = (MATERIAL_COLOR_SPACE, TAG, *POSE)  # listed once, in "Inputs every object takes"
_PRESETS: tuple[type[Material], ...] = (
    DiffuseMaterial,
    MetalMaterial,
    PlasticMaterial,
    PlasticWireframeMaterial,
    MetalWireframeMaterial,
)
_LIGHTS: tuple[type[Declared], ...] = (PointLight, SunLight, SpotLight, AreaLight, BackgroundLight, EnvironmentMap)


def _value(v: Any) -> str:
    if v is REQUIRED:
        return "required"
    if isinstance(v, bool) or v is None:
        return str(v)
    if isinstance(v, float):
        return f"{v:g}"
    if isinstance(v, str):
        return f'"{v}"'
    if isinstance(v, tuple):
        return "(" + ", ".join(_value(x) for x in v) + ")"
    return repr(v)


def _cell(text: str) -> str:
    return text.replace("``", "`").replace("|", "\\|") if text else "-"


def _summary(cls: type) -> str:
    """The first paragraph of the class docstring, on one line."""
    paragraph = (cls.__doc__ or "").strip().split("\n\n")[0]
    return " ".join(line.strip() for line in paragraph.splitlines()).replace("``", "`")


def _rows(params: Iterable[Param]) -> list[str]:
    out = [
        "| parameter | type | default | range | unit | Blender clamp | meaning |",
        "|---|---|---|---|---|---|---|",
    ]
    for p in params:
        kind = p.type_description + ("" if p.stored else " (constructor input)") + (", fixed" if p.fixed else "")
        cells = [f"`{p.name}`", kind, _value(p.default), p.range_text(), p.unit, p.clamp_text(), p.doc]
        out.append("| " + " | ".join(_cell(c) for c in cells) + " |")
    return out


def _own(cls: type[Declared], exclude: Sequence[Param] = ()) -> list[Param]:
    shared = {id(p) for p in _SHARED} | {id(p) for p in exclude}
    return [p for p in cls._declared if id(p) not in shared and p.name not in ("tag", *(q.name for q in POSE))]


def _signature_line(cls: type) -> str:
    names = list(cls._positional)  # type: ignore[attr-defined]
    return f"`{cls.__name__}({', '.join(names)}{', ' if names else ''}**kwargs)`"


def parameters_markdown() -> str:
    """The whole of docs/parameters.md."""
    lines = [
        "# Parameters of materials and lights",
        "",
        "Generated from the declarations in `blendify_core/ir/materials.py` and `blendify_core/ir/lights.py`",
        "by `python -m blendify_core.ir.paramdocs`; do not edit by hand (a test checks that this file is current).",
        "",
        "Every parameter is an attribute (`material.roughness`, `light.strength`), validated on every",
        "assignment by the one policy of [conventions.md](conventions.md#validation-policy): a value outside its",
        "range raises `InvalidSceneError` naming the parameter; a value in a Blender clamp range is replaced by",
        "what Blender renders it as, with a `BlenderClampWarning` naming the parameter. Ranges: `[a, b]` includes",
        "both ends, `(` / `)` excludes one. Colours are sRGB-encoded unless the object is created with",
        '`color_space="linear"`.',
        "",
        "## Materials",
        "",
        "### PrincipledBSDFMaterial",
        "",
        "Blender's Principled BSDF with blendify's names and defaults. The base colour comes from the object's",
        "colour source (`colors=`), not from the material.",
        "",
        *_rows(_own(PrincipledBSDFMaterial)),
        "",
        "### Presets",
        "",
        "Principled materials with other defaults; every Principled parameter is accepted by keyword, except",
        "where a preset lists what it accepts (the others keep the preset's value; passing one raises).",
        "",
        "| class | signature | defaults changed from PrincipledBSDFMaterial |",
        "|---|---|---|",
    ]
    for cls in _PRESETS:
        changed = ", ".join(f"`{k}` {_value(v)}" for k, v in cls._preset.items())
        if cls._settable is not None:
            changed += "; accepts only " + ", ".join(f"`{n}`" for n in cls._settable)
        lines.append(f"| `{cls.__name__}` | {_signature_line(cls)} | {changed} |")
    lines += [
        "",
        "### PrincipledBSDFWireframeMaterial",
        "",
        "A Principled surface with the triangle edges drawn over it; its own parameters (every Principled",
        "parameter is accepted too):",
        "",
        *_rows(_own(PrincipledBSDFWireframeMaterial, exclude=_own(PrincipledBSDFMaterial))),
        "",
        "### GlossyBSDFMaterial",
        "",
        "Blender's Glossy BSDF, tinted by the object's colour.",
        "",
        *_rows(_own(GlossyBSDFMaterial)),
        "",
        "## Lights",
        "",
    ]
    for light in _LIGHTS:
        lines += [f"### {light.__name__}", "", _summary(light), "", *_rows(_own(light)), ""]
    lines += [
        "## Inputs every object takes",
        "",
        "Materials take `color_space`; positioned lights take `color_space` (a parameter, listed above), the",
        "pose and `tag`; `add_*` methods list the pose and `tag` after the class's own parameters.",
        "",
        *_rows(_SHARED),
        "",
    ]
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    path = Path(args[0]) if args else Path("docs/parameters.md")
    path.write_text(parameters_markdown(), encoding="utf-8")
    return 0


if __name__ == "__main__":
    main()
