"""Rendering a translated scene (:class:`~blendify_blender.session.BuiltScene`) into a RenderResult.

The passes are written by a compositor File Output node as one single-layer 32-bit EXR per pass into
a private temporary directory (removed afterwards), then read with ``openexr``. Single-layer files are
used because Blender 5.0's multilayer EXR writer fails whenever the pixel aspect is not 1 (fx != fy,
CONVENTIONS.md section 13); with square pixels both ways give bit-identical values.
"""

from __future__ import annotations

import glob
import os
import shutil
import tempfile
import time
from typing import Any

import numpy as np

from blendify_core.errors import RenderError
from blendify_core.pipeline.result import RenderResult
from blendify_core.pipeline.settings import RenderSettings

from .materials import ALBEDO_AOV, NORMAL_AOV
from .session import BuiltScene, bpy_module, capture_output, engine_errors

__all__ = ["render_built", "sample_window", "set_sample_window", "PASSES"]

#: output name -> (view-layer flag, Render Layers socket, file item name, item socket type)
PASSES: dict[str, tuple[str | None, str, str, str]] = {
    "rgb": (None, "Image", "rgba", "RGBA"),
    "depth": ("use_pass_z", "Depth", "depth", "FLOAT"),
    "normal": ("use_pass_normal", "Normal", "normal", "VECTOR"),
    "instance": ("use_pass_object_index", "Object Index", "instance", "FLOAT"),
    "albedo": (None, ALBEDO_AOV, "albedo", "RGBA"),
}
#: the IR materials' shading normal (materials.NORMAL_AOV), written beside Cycles' Normal pass: the pass
#: fills the pixels of objects rendered from an attached file's own node trees, which write no such AOV
_NORMAL_AOV_ITEM = ("normal_aov", "RGBA")
_BACKGROUND_DEPTH = 1e9  # Cycles writes 1e10 where nothing was hit
#: the passes Cycles writes from each pixel's first sample only
_FIRST_SAMPLE_PASSES = ("depth", "instance")
#: Cycles' largest sample count and sample offset
_MAX_CYCLES_SAMPLES = 1 << 24


def sample_window(samples: int, passes: tuple[str, ...]) -> int:
    """The index of the first sample a colour render of ``samples`` per pixel renders (Cycles' sample
    offset; 0: Cycles' own first samples).

    Cycles puts the first sample of every pixel (index 0) at the pixel centre, whatever the seed, and so
    does no other engine: a render at 1 spp is the same for every seed, and every render carries one sample
    that does not average over the pixel's area. At a silhouette that is a bias of weight 1/samples that does
    not fall with more independent passes (each pass carries one), and a between-pass error estimate cannot
    see it. A colour render therefore renders the samples ``[B, B + samples)``, B the smallest power of two
    >= ``samples``: the leading part of an aligned block of Cycles' scrambled Sobol sequence, as well
    stratified as its first samples (measured: a 1x1 render of a sphere's edge at 16 spp, 200 seeds: mean
    coverage 0.5466 with index 0, 0.5153 with the window, converged 0.5168; RMS error 0.052 -> 0.030).
    Cycles writes the depth and object-index passes (:data:`_FIRST_SAMPLE_PASSES`) from index 0 only: a render
    of one of them keeps index 0 (:func:`render_built` renders them apart from the colour: exact at the
    pixel centre, as the output contract says)."""
    if any(p in passes for p in _FIRST_SAMPLE_PASSES) or "rgb" not in passes:
        return 0
    block = 1 << max(0, int(samples) - 1).bit_length()
    if block + samples <= _MAX_CYCLES_SAMPLES:
        return block
    return 1 if samples < _MAX_CYCLES_SAMPLES else 0


def set_sample_window(cy: Any, samples: int, passes: tuple[str, ...] = ("rgb",)) -> int:
    """Set Cycles' settings ``cy`` to render ``samples`` per pixel from :func:`sample_window`'s first index (a
    sample subset of ``offset + samples``); returns the offset (0: Cycles' own samples, no subset)."""
    offset = sample_window(samples, passes)
    cy.samples = offset + samples
    cy.use_sample_subset = bool(offset)
    if offset:
        cy.sample_offset = offset
        cy.sample_subset_length = samples
    return offset


def _setup_passes(built: BuiltScene, outputs: tuple[str, ...], directory: str) -> None:
    bpy = bpy_module()
    sc = built.bscene
    vl = sc.view_layers[0]
    vl.use_pass_combined = True
    vl.use_pass_z = "depth" in outputs
    vl.use_pass_normal = "normal" in outputs
    vl.use_pass_object_index = "instance" in outputs
    for aov in list(vl.aovs):
        vl.aovs.remove(aov)
    for name, wanted in ((ALBEDO_AOV, "albedo"), (NORMAL_AOV, "normal")):
        if wanted in outputs:
            aov = vl.aovs.add()
            aov.name = name
            aov.type = "COLOR"
    built.compositor.remove()
    ng = built.compositor.add("node_groups", bpy.data.node_groups.new("bf_outputs", "CompositorNodeTree"))
    sc.compositing_node_group = ng
    sc.render.use_compositing = True
    sc.render.use_sequencer = False
    rl = ng.nodes.new("CompositorNodeRLayers")
    rl.scene = sc
    rl.layer = vl.name
    fo = ng.nodes.new("CompositorNodeOutputFile")
    fo.directory = directory + os.sep
    fo.file_name = "bf_"
    fo.save_as_render = False
    f = fo.format
    f.media_type = "IMAGE"
    f.file_format = "OPEN_EXR"
    f.color_depth = "32"
    f.exr_codec = "ZIP"
    # the Image socket is always written: Blender needs one output to run the compositor
    wanted = ["rgb", *[o for o in outputs if o != "rgb"]]
    for out in wanted:
        _, socket, item, stype = PASSES[out]
        fo.file_output_items.new(stype, item)
        ng.links.new(rl.outputs[socket], fo.inputs[item])
    if "normal" in outputs:
        item, stype = _NORMAL_AOV_ITEM
        fo.file_output_items.new(stype, item)
        ng.links.new(rl.outputs[NORMAL_AOV], fo.inputs[item])
    sc.render.filepath = os.path.join(directory, "unused_")


def _read_exr(path: str) -> dict[str, np.ndarray]:
    import OpenEXR

    out: dict[str, np.ndarray] = {}
    with OpenEXR.File(path, separate_channels=True) as f:
        for part in f.parts:
            for name, ch in part.channels.items():
                out[name.rsplit(".", 1)[-1]] = np.asarray(ch.pixels, dtype=np.float32)
    return out


def _find(directory: str, item: str) -> str:
    hits = sorted(glob.glob(os.path.join(directory, f"bf_{item}*.exr")))
    if not hits:
        raise RenderError(f"cycles: Blender did not write the {item!r} pass (files: {os.listdir(directory)})")
    return hits[0]


def _render(built: BuiltScene, passes: tuple[str, ...], directory: str, cap: Any, samples: int | None = None) -> int:
    """One Cycles render of ``passes`` into ``directory`` (``samples``: instead of the scene's); returns the
    sample offset it rendered from (:func:`sample_window`). The scene keeps its plain sample settings."""
    bpy = bpy_module()
    with engine_errors("setting up the render passes", cap):
        _setup_passes(built, passes, directory)
    cy = built.bscene.cycles
    own = int(cy.samples)
    try:
        with engine_errors("rendering", cap):
            offset = set_sample_window(cy, own if samples is None else int(samples), passes)
            res = bpy.ops.render.render(write_still=False, scene=built.bscene.name)
            if "FINISHED" not in res:
                raise RuntimeError(f"render operator returned {sorted(res)}")
    finally:  # the built scene (and a .blend exported from it) keeps plain sample settings
        cy.use_sample_subset = False
        cy.samples = own
    return offset


def render_built(built: BuiltScene, settings: RenderSettings, verbose: bool = False) -> RenderResult:
    """Render the translated scene with Cycles; return the requested outputs as a RenderResult.

    Colour skips Cycles' fixed first sample (:func:`sample_window`); the geometric outputs come from that
    sample, the pixel-centre ray (Cycles writes depth and object index from it only), in a render of one
    sample of their own, so the colour does not depend on the other outputs asked for."""
    outputs = tuple(settings.outputs)
    timings: dict[str, float] = {}
    directory = tempfile.mkdtemp(prefix="blendify_cycles_")
    geometry_dir = os.path.join(directory, "first_sample")
    try:
        t0 = time.perf_counter()
        # the geometric outputs from the pixel-centre sample, as in the other engines; the depth pass also
        # tells where nothing was hit, so the normal and albedo passes can be 0 there as the output contract says
        geometric = tuple(p for p in outputs if p != "rgb")
        if ("normal" in outputs or "albedo" in outputs) and "depth" not in outputs:
            geometric = (*geometric, "depth")
        passes, apart = (("rgb",), geometric) if "rgb" in outputs and geometric else (outputs + geometric, ())
        passes = tuple(dict.fromkeys(passes))
        with capture_output("render", verbose) as cap:
            offset = _render(built, passes, directory, cap)
            t1 = time.perf_counter()
            if apart:
                os.makedirs(geometry_dir)
                _render(built, apart, geometry_dir, cap, samples=1)
        t2 = time.perf_counter()
        timings["cycles"] = t1 - t0
        if apart:
            timings["first_sample_render"] = t2 - t1
        timings["render"] = t2 - t0  # set-up and the Cycles renders (a common timing key)
        result = RenderResult()
        rgba = _read_exr(_find(directory, "rgba"))
        if "rgb" in outputs:
            result.rgba = np.stack([rgba["R"], rgba["G"], rgba["B"], rgba["A"]], axis=-1)
        miss = None
        geo_dir = geometry_dir if apart else directory
        if "depth" in geometric:
            z = _read_exr(_find(geo_dir, "depth"))
            d = z.get("R", z.get("Z", z.get("V")))
            if d is None:
                raise RenderError(f"cycles: unexpected depth channels {sorted(z)}")
            miss = d >= _BACKGROUND_DEPTH
            if "depth" in outputs:
                result.depth = np.where(miss, np.inf, d).astype(np.float32)
        if "normal" in outputs:
            n = _read_exr(_find(geo_dir, "normal"))
            nrm = np.stack([n["X"], n["Y"], n["Z"]], axis=-1)
            a = _read_exr(_find(geo_dir, _NORMAL_AOV_ITEM[0]))
            aov = np.stack([a["R"], a["G"], a["B"]], axis=-1)
            # the IR materials' normal AOV; Cycles' pass where no IR material wrote it (attached files)
            nrm = np.where(np.linalg.norm(aov, axis=-1, keepdims=True) > 1e-6, aov, nrm)
            length = np.linalg.norm(nrm, axis=-1, keepdims=True)
            hit = (length > 1e-6) if miss is None else (length > 1e-6) & ~miss[..., None]
            result.normal = np.divide(nrm, length, out=np.zeros_like(nrm), where=hit).astype(np.float32)
        if "instance" in outputs:
            ix = _read_exr(_find(geo_dir, "instance"))
            idx = ix.get("R", ix.get("X", ix.get("V")))
            if idx is None:
                raise RenderError(f"cycles: unexpected object-index channels {sorted(ix)}")
            result.instance = (np.rint(idx).astype(np.int32) - 1).astype(np.int32)
        if "albedo" in outputs:
            a = _read_exr(_find(geo_dir, "albedo"))
            albedo = np.stack([a["R"], a["G"], a["B"]], axis=-1).astype(np.float32)
            if miss is not None:
                albedo[miss] = 0.0
            result.albedo = albedo
        timings["read_back"] = time.perf_counter() - t2  # the EXR passes read back (a common timing key)
        result.instance_tags = list(built.instance_tags)
        result.meta["timings"] = timings
        result.meta["engine_settings"] = {**built.engine_settings, "sample_offset": offset}
        result.meta["samples"] = int(built.engine_settings.get("samples", settings.samples))
        result.meta["log_tail"] = cap.lines[-5:]
        result.meta["translation"] = dict(built.stats)
        if built.stats.get("ir_limits"):  # attached objects rendered from their IR parse
            result.meta["approximations"] = list(built.stats["ir_limits"])
        return result
    finally:
        shutil.rmtree(directory, ignore_errors=True)
