"""Indirect light for the preview: light probes.

The preview shades with direct light and the world's light (9 spherical-harmonic coefficients, shaders/
blendify_env.glsl). Light that bounces off other surfaces is missing: a closed room is black where no lamp
shines, the underside of an object on a lit floor gets only the sky. A probe adds it: a small cube map
(6 faces of ``PROBE_SIZE``^2 texels) rendered by the preview itself from a point of the scene, emission
left out (the emitters already light the scene as lights), the world's radiance where a texel sees nothing,
projected onto the same 9 coefficients. Rendering the probes again lit by their own coefficients adds a
bounce (``PROBE_BOUNCES``).

The probes form a grid over the solid objects (:func:`probe_grid`: up to ``GRID`` along the longest axis,
one at each cell's centre, inside the bounds of all objects); each fragment interpolates the coefficients of
the 8 nearest probes trilinearly (a float texture, BLENDIFY_PROBE_GRID in blendify_env.glsl): a wall far from
the lit floor gets less than one next to it. No occlusion nearer than the probes' spacing (no contact
shadows). Objects whose bounds hold a probe are hidden from it. Scenes whose probes would draw too many
triangles (``GRID_BUDGET``) get one probe for the whole scene, at :func:`probe_point`. The probe at that
point also gives metals and solid glass holding it their surroundings (an equirectangular map).

The probes depend on the scene, not on the camera: they are cached for as long as the geometry, lights and
world stay the same (the frame's shadow key), so a moving camera pays nothing; their renders set each
program's light uniforms once (``FrameRenderer.lighting_cache``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from .translate import sh_basis

if TYPE_CHECKING:
    from .session import Engine, Frame

__all__ = [
    "PROBE_SIZE",
    "PROBE_BOUNCES",
    "GRID",
    "ProbeGrid",
    "probe_grid",
    "probe_point",
    "cube_directions",
    "world_radiance",
    "probe_sh",
]

#: texels per cube face edge
PROBE_SIZE = 16
#: renders of the probes: 1 = one bounce of light, each more adds one
PROBE_BOUNCES = 2
#: how much of the world's light the probe sees hidden is taken away (1 = all of it): one point's view stands
#: for every surface's, so it hides too much for some and too little for others; half measured best (SSIM
#: against Cycles over benchmarks/preview_look.py, within 0.002 of 0 and 1 on the means)
PROBE_OCCLUSION = 0.5
#: objects thinner than this fraction of the scene's diagonal along some axis are "flat" (walls, floors): the
#: probe's point is chosen among the others
FLAT_FRACTION = 0.01
#: probes along the longest axis of the grid of probes (1: one probe for the whole scene)
GRID = 3
#: the grid's box: the solid objects' bounds grown on every side by this fraction of their size
GRID_GROW = 0.5
#: at most this many triangles drawn by the renders of the grid's probes (6 per probe): coarser grids, then one
#: probe, for larger scenes
GRID_BUDGET = 3_000_000
#: rows of the probe's equirectangular map that metals reflect (shaders/blendify_env.glsl)
MAP_HEIGHT = 32
#: the cosine lobe's band factors A_l / pi (shaders/blendify_env.glsl, translate._SH_BAND_FACTOR)
_BAND = np.array([1.0, 2 / 3, 2 / 3, 2 / 3, 0.25, 0.25, 0.25, 0.25, 0.25])
#: camera-to-world rotations of the six faces: columns (right, up, backward); OpenGL cameras look along -Z
_FACES = []
for _fwd, _up in (
    ((1, 0, 0), (0, 0, 1)),
    ((-1, 0, 0), (0, 0, 1)),
    ((0, 1, 0), (0, 0, 1)),
    ((0, -1, 0), (0, 0, 1)),
    ((0, 0, 1), (0, 1, 0)),
    ((0, 0, -1), (0, 1, 0)),
):
    _f, _u = np.array(_fwd, dtype=np.float64), np.array(_up, dtype=np.float64)
    _FACES.append(np.stack([np.cross(_f, _u), _u, -_f], axis=1))


def cube_directions(n: int) -> tuple[list[np.ndarray], np.ndarray]:
    """Per face the (n*n, 3) unit world directions through the texel centres (rows top to bottom, as the
    colour pass returns them), and the (n*n,) solid angle of each texel (the same on every face)."""
    c = (np.arange(n) + 0.5) / n * 2.0 - 1.0
    x, y = np.meshgrid(c, -c)  # image rows go down, y up
    x, y = x.reshape(-1), y.reshape(-1)
    r2 = 1.0 + x * x + y * y
    d_omega = (2.0 / n) ** 2 / r2**1.5
    d_omega *= 4.0 * np.pi / (6.0 * d_omega.sum())  # the midpoint rule's 0.4 % (n = 8) off the sphere
    dirs = []
    for rot in _FACES:
        d = x[:, None] * rot[:, 0] + y[:, None] * rot[:, 1] - rot[:, 2]
        dirs.append(d / np.sqrt(r2)[:, None])
    return dirs, d_omega


def equirect_from_cube(faces: list[np.ndarray], n: int, height: int) -> np.ndarray:
    """(height, 2 height, 3) equirectangular map (row 0 = +Z, polar angle (i + 0.5) / height x pi; column j =
    azimuth (j + 0.5) / width x 2 pi - pi from +X toward +Y) of the six faces' (n*n, 3) radiances (nearest texel)."""
    width = 2 * height
    theta = (np.arange(height) + 0.5) / height * np.pi
    phi = (np.arange(width) + 0.5) / width * 2.0 * np.pi - np.pi
    theta, phi = np.meshgrid(theta, phi, indexing="ij")
    d = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], axis=-1).reshape(-1, 3)
    out = np.zeros((d.shape[0], 3))
    fwd = np.stack([-rot[:, 2] for rot in _FACES])  # (6, 3)
    face = np.argmax(d @ fwd.T, axis=1)
    for k, rot in enumerate(_FACES):
        m = face == k
        dk = d[m]
        z = dk @ -rot[:, 2]
        x, y = (dk @ rot[:, 0]) / z, (dk @ rot[:, 1]) / z
        col = np.clip(((x + 1.0) * 0.5 * n).astype(np.int64), 0, n - 1)
        row = np.clip(((1.0 - y) * 0.5 * n).astype(np.int64), 0, n - 1)
        out[m] = faces[k][row * n + col]
    return out.reshape(height, width, 3)


def world_radiance(sh: np.ndarray, d: np.ndarray) -> np.ndarray:
    """(N, 3) radiance of the world in directions ``d`` from its coefficients (A_l / pi) L_lm."""
    return np.clip(sh_basis(d) @ (np.asarray(sh, dtype=np.float64) / _BAND[:, None]), 0.0, None)


def probe_point(boxes: list[tuple[Any, np.ndarray, np.ndarray]], diagonal: float) -> tuple[np.ndarray, list[Any]]:
    """Where the probe is rendered from and which objects it does not see. ``boxes``: (node, world min, world
    max) of the visible objects. The point: the centre of the bounds of the objects that are not flat; the
    objects whose bounds (grown by 0.1 % of the diagonal) hold it are hidden (the probe would be inside them,
    or on their surface). When every object is flat, every object is hidden (no probe: the world's light)."""
    solid = [b for b in boxes if float(np.min(b[2] - b[1])) > FLAT_FRACTION * diagonal]
    if not solid:  # only flat objects (stacked planes, a lone wall): no point between them is better
        return np.zeros(3), [node for node, _, _ in boxes]
    lo = np.min([b[1] for b in solid], axis=0)
    hi = np.max([b[2] for b in solid], axis=0)
    point = 0.5 * (lo + hi)
    eps = 1e-3 * diagonal
    hidden = [node for node, mn, mx in boxes if np.all(point >= mn - eps) and np.all(point <= mx + eps)]
    return point, hidden


def _node_box(scene: Any, node: Any) -> tuple[np.ndarray, np.ndarray]:
    b = np.asarray(node.mesh.bounds, dtype=np.float64)
    corners = np.array([[b[i, 0], b[j, 1], b[k, 2]] for i in (0, 1) for j in (0, 1) for k in (0, 1)])
    pose = scene.get_pose(node)
    w = corners @ pose[:3, :3].T + pose[:3, 3]
    return w.min(axis=0), w.max(axis=0)


def probe_grid(
    boxes: list[tuple[Any, np.ndarray, np.ndarray, int]], diagonal: float
) -> tuple[np.ndarray, np.ndarray, tuple[int, int, int], list[np.ndarray], list[list[Any]]] | None:
    """A grid of probes for the indirect light. ``boxes``: (node, world min, world max, triangles) of the
    visible objects. The grid's box: the bounds of the objects that are not flat, grown by ``GRID_GROW`` of
    their size on every side, kept inside the bounds of all objects (the room's walls, the floor); up to
    ``GRID`` probes along its longest axis, fewer along shorter ones, one per cell at the cell's centre, fewer
    while the probes' renders would draw more than ``GRID_BUDGET`` triangles. Each probe does not see the
    objects whose bounds hold it (as :func:`probe_point`). Returns (box min, box max, (nx, ny, nz), points in
    x-fastest order, hidden nodes per point), or None when a grid of one probe is all the budget allows or
    every object is flat."""
    diag = max(diagonal, 1e-12)
    solid = [b for b in boxes if float(np.min(b[2] - b[1])) > FLAT_FRACTION * diag]
    if not solid:
        return None
    lo = np.min([b[1] for b in solid], axis=0)
    hi = np.max([b[2] for b in solid], axis=0)
    grow = GRID_GROW * (hi - lo)
    lo = np.maximum(lo - grow, np.min([b[1] for b in boxes], axis=0))
    hi = np.minimum(hi + grow, np.max([b[2] for b in boxes], axis=0))
    size = hi - lo
    eps = 1e-3 * diag
    for n_max in range(GRID, 1, -1):
        dims = tuple(int(np.clip(round(n_max * s / max(size.max(), 1e-12)), 1, n_max)) for s in size)
        axes = [lo[a] + (np.arange(dims[a]) + 0.5) / dims[a] * size[a] for a in range(3)]
        points = [np.array([x, y, z]) for z in axes[2] for y in axes[1] for x in axes[0]]
        hidden = [
            [node for node, mn, mx, _ in boxes if np.all(p >= mn - eps) and np.all(p <= mx + eps)] for p in points
        ]
        drawn = sum(tris for h in hidden for node, _, _, tris in boxes if node not in h)
        if len(points) > 1 and 6 * PROBE_BOUNCES * drawn <= GRID_BUDGET:
            return lo, hi, dims, points, hidden  # type: ignore[return-value]
    return None


@dataclass
class ProbeGrid:
    """The indirect light of a grid of probes: the grid's box (``lo``, ``hi``), probes per axis ``dims`` (one
    at each cell's centre) and their (nx ny nz, 9, 3) coefficients (A_l / pi) L_lm, x fastest."""

    lo: np.ndarray
    hi: np.ndarray
    dims: tuple[int, int, int]
    sh: np.ndarray


def probe_sh(engine: Engine, frame: Frame, flags: int, render_rgba: Any) -> tuple[np.ndarray, ProbeGrid | None, str]:
    """The indirect light: the 9 coefficients (A_l / pi) L_lm (linear RGB) of one probe (the mean of the
    grid's when there is a grid), the grid of probes (:func:`probe_grid`; None: one probe for the whole
    scene, at :func:`probe_point`) and a note on how it was rendered (the world's coefficients, no grid and no
    note when no probe would see an object).
    ``render_rgba(width, height)`` renders the colour pass of the current camera as linear premultiplied
    RGBA. The renderer's camera, visibility, shadow key, emission, world coefficients and grid are restored
    (the grid is left unset: the caller sets the returned one)."""
    from .render import FrameRenderer

    r: FrameRenderer = engine.renderer
    scene = engine.pscene
    nodes = [n for n in frame.nodes if n is not None and n.mesh.is_visible]
    diagonal = float(scene.scale) if nodes else 1.0
    boxes = [(n, *_node_box(scene, n)) for n in nodes]
    point, hidden = probe_point(boxes, diagonal)
    grid = probe_grid([(n, mn, mx, _triangles(n)) for n, mn, mx in boxes], diagonal) if GRID > 1 else None
    world = np.asarray(r.env_sh, dtype=np.float64).copy()
    for n in nodes:  # metals reflect the probe's view only when it was rendered from inside them
        for prim in n.mesh.primitives:
            prim.blendify_probe_inside = n in hidden
    r.set_probe_grid(None)
    if len(hidden) == len(nodes):  # nothing left to see: the world's light
        r.set_probe_map(None)
        return world, None, ""
    cam_node = scene.main_camera_node
    cam = cam_node.camera
    saved = (cam.projection, cam.znear, cam.zfar, scene.get_pose(cam_node).copy())
    near, far = 1e-3 * diagonal, 4.0 * diagonal
    proj = np.zeros((4, 4))
    proj[0, 0] = proj[1, 1] = 1.0  # 90 degrees
    proj[2, 2], proj[2, 3] = -(far + near) / (far - near), -2.0 * far * near / (far - near)
    proj[3, 2] = -1.0
    dirs, d_omega = cube_directions(PROBE_SIZE)
    basis = [sh_basis(d) * d_omega[:, None] for d in dirs]
    background = [world_radiance(world, d) for d in dirs]
    key, emission = r.shadow_key, r.emission_scale
    # the frame's shadow maps, drawn before anything is hidden: the hidden objects still cast their shadows
    # (the floor under a ball stays dark in the probe's view), and the frame reuses them
    r.shadow_maps(scene, flags)
    r.emission_scale = 0.0
    cam.projection, cam.znear, cam.zfar = proj, near, far
    # what the metals' map shows where the probe sees nothing: the environment map itself when there is one
    sky = [frame.sky(d) if frame.sky is not None else bg for d, bg in zip(dirs, background)]
    r.probe_scale = 0.0  # the probe does not see its own (stale) map
    r.lighting_cache = {}  # the same lights for every face: light uniforms set once per program

    def render_probe(at: np.ndarray, hide: list[Any]) -> tuple[np.ndarray, list[np.ndarray]]:
        """(the probe's coefficients, what it sees per face) at ``at`` with ``hide`` hidden."""
        for n in hide:
            n.mesh.is_visible = False
        acc, seen = np.zeros((9, 3)), []
        try:
            for rot, b, bg, sky_k in zip(_FACES, basis, background, sky):
                pose = np.eye(4)
                pose[:3, :3], pose[:3, 3] = rot, at
                scene.set_pose(cam_node, pose)
                rgba = render_rgba(PROBE_SIZE, PROBE_SIZE).reshape(-1, 4).astype(np.float64)
                acc += b.T @ (rgba[:, :3] + (1.0 - PROBE_OCCLUSION * rgba[:, 3:4]) * bg)
                seen.append(rgba[:, :3] + (1.0 - rgba[:, 3:4]) * sky_k)
        finally:
            for n in hide:
                n.mesh.is_visible = True
        return acc * _BAND[:, None], seen

    metals = any(_reflects(prim) for n in hidden for prim in n.mesh.primitives)
    seen: list[np.ndarray] = []
    out: ProbeGrid | None = None
    try:
        sh = world
        for _ in range(PROBE_BOUNCES):
            r.env_sh = r.spec_sh = sh.astype(np.float32)  # the previous bounce's light (the world's at first)
            if grid is None:
                sh, seen = render_probe(point, hidden)
                continue
            lo, hi, dims, points, hides = grid
            out = ProbeGrid(lo, hi, dims, np.stack([render_probe(p, h)[0] for p, h in zip(points, hides)]))
            r.set_probe_grid(out)  # the next bounce is lit by it
            sh = out.sh.mean(axis=0)
        if metals:
            # the map, lit by the last bounce's light; solid glass casts its shadow in it when the shadows let
            # its light through (render.CAUSTICS), else none: the light a glass ball lets through reaches the
            # floor under it, which is what the ball shows
            r.env_sh = r.spec_sh = sh.astype(np.float32)
            glass = {n for n in nodes if any(_reflects(p) and not _is_metal(p) for p in n.mesh.primitives)}
            if r._program_cache.caustic:
                glass = set()
            casting, r.no_shadow_nodes = r.no_shadow_nodes, r.no_shadow_nodes | glass
            try:
                if glass:
                    r.shadow_key = None if key is None else (key, "probe map")
                    r.shadow_maps(scene, flags)
                seen = render_probe(point, hidden)[1]
            finally:
                r.no_shadow_nodes = casting
    finally:
        r.lighting_cache = None
        r.set_probe_grid(None)
        r.shadow_key, r.emission_scale, r.probe_scale = key, emission, 1.0
        r.env_sh = r.spec_sh = world.astype(np.float32)
        cam.projection, cam.znear, cam.zfar = saved[0], saved[1], saved[2]
        scene.set_pose(cam_node, saved[3])
    # the map metals reflect: only for metals the probe was rendered inside (their surroundings)
    # the surroundings' box: what the map shows is taken to lie on it (parallax, shaders/blendify_env.glsl)
    surroundings = (np.min([b[1] for b in boxes], axis=0), np.max([b[2] for b in boxes], axis=0))
    r.set_probe_map(equirect_from_cube(seen, PROBE_SIZE, MAP_HEIGHT) if metals else None, point, surroundings)
    if out is None:
        where = ", ".join(f"{v:.3g}" for v in point)
        note = (
            f"indirect light: one light probe at ({where}) ({PROBE_BOUNCES} bounces, a cube of 6 x {PROBE_SIZE}^2 "
            "texels rendered by the preview, emission left out) replaces the world's light as 9 spherical-harmonic "
            f"coefficients; {len(hidden)} object(s) holding that point hidden from it; no occlusion nearer than "
            "the probe's surroundings (no contact shadows)"
        )
    else:
        note = (
            f"indirect light: a grid of {out.dims[0]} x {out.dims[1]} x {out.dims[2]} light probes over the solid "
            f"objects ({PROBE_BOUNCES} bounces, each a cube of 6 x {PROBE_SIZE}^2 texels rendered by the preview, "
            "emission left out, objects whose bounds hold a probe hidden from it) replaces the world's light as 9 "
            "spherical-harmonic coefficients interpolated trilinearly between the probes; no occlusion nearer "
            "than the probes' spacing (no contact shadows)"
        )
    return sh, out, note


def _is_metal(primitive: Any) -> bool:
    return bool(getattr(primitive.material, "metallicFactor", 0.0) > 0.0)


def _reflects(primitive: Any) -> bool:
    """Whether a primitive shows the probe's map when the probe is inside it: a metal or solid glass (its
    refraction and reflection)."""
    from .render import _is_solid

    if _is_metal(primitive):
        return True
    glass = getattr(primitive.material, "blendify_glass", None)
    return glass is not None and float(glass[0]) > 0.0 and _is_solid(primitive)


def _triangles(node: Any) -> int:
    """Triangles (points) a render of ``node`` draws."""
    total = 0
    for prim in node.mesh.primitives:
        idx = prim.indices if prim.indices is not None else prim.positions
        total += int(np.asarray(idx).shape[0])
    return total
