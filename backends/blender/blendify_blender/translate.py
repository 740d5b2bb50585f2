"""IR -> bpy translation for the Cycles backend: :class:`CyclesTranslator`, one handler per IR type.

Where each IR type becomes bpy data (one ``@handles`` method each, its capabilities declared beside it):

- renderables: :meth:`~CyclesTranslator.mesh`, :meth:`~CyclesTranslator.pointcloud` (native Cycles points:
  a vertex-only mesh + Geometry Nodes Mesh to Points), :meth:`~CyclesTranslator.primitive` (cube, circle,
  cylinder), :meth:`~CyclesTranslator.plane`, :meth:`~CyclesTranslator.sphere`,
  :meth:`~CyclesTranslator.ellipsoid` (the IR's shared tessellation, one mesh shared by identical
  primitives), :meth:`~CyclesTranslator.curve` (the IR's tube, not shared);
- materials (node trees built by :class:`~blendify_blender.materials.MaterialBuilder`):
  :meth:`~CyclesTranslator.principled` (the Principled family), :meth:`~CyclesTranslator.wireframe`,
  :meth:`~CyclesTranslator.glossy`;
- colour sources: :meth:`~CyclesTranslator.uniform_colors`, :meth:`~CyclesTranslator.vertex_colors`,
  :meth:`~CyclesTranslator.texture_colors`, :meth:`~CyclesTranslator.file_texture_colors` (each returns a
  :class:`ColorFeed`: the nodes that give a material its base colour, plus per-vertex data);
- lights (:meth:`~CyclesTranslator.point_light`, ``sun_light``, ``spot_light``, ``area_light``: Blender's
  units are the IR's, soft falloff off, area ``normalize`` on, invisible to camera rays), the world
  (``background_light``, ``environment_map``), cameras (``perspective_camera``: ``HORIZONTAL`` sensor fit,
  lens from fx, principal point through the shift, fx != fy through the pixel aspect;
  ``orthographic_camera``) and attached files (:meth:`~CyclesTranslator.attachment`: the unparsed content of
  an attached .blend).

:meth:`CyclesTranslator.translate` walks a scene with the core's
:class:`~blendify_core.pipeline.changes.SceneChanges` (everything when ``changes.first``): new and changed
renderables are built, moved ones get a new matrix, lights and world are rebuilt when they changed, the
camera and every Cycles setting (:func:`apply_engine_settings`) are applied every time. The incremental
state lives in :mod:`blendify_blender.session`.

``build_scene(scene, settings=None, reset=True) -> BuiltScene`` builds the whole bpy scene for a
blendify-core :class:`~blendify_core.Scene` in the current bpy session (after a factory reset unless
``reset=False``); the .blend export uses it. ``BuiltScene.remove()`` deletes every datablock it created.

Everything goes through the data API with bulk ``foreach_set`` of numpy arrays; no ``bpy.ops`` except
the factory reset. Conventions (camera, lights, colour) follow ``shared/docs/CONVENTIONS.md``.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from blendify_blender.blendfile.linking import FileContent, append_blend_content
from blendify_blender.blendfile.origins import FilePlan, file_plan
from blendify_blender.blendfile.settings import CYCLES_KEYS
from blendify_core.errors import InvalidSceneError
from blendify_core.ir.attachments import Attachment
from blendify_core.ir.cameras import OrthographicCamera, PerspectiveCamera
from blendify_core.ir.colors import FileTextureColors, TextureColors, UniformColors, VertexColors
from blendify_core.ir.lights import AreaLight, BackgroundLight, EnvironmentMap, PointLight, SpotLight, SunLight
from blendify_core.ir.materials import (
    DiffuseMaterial,
    GlossyBSDFMaterial,
    MetalMaterial,
    MetalWireframeMaterial,
    PlasticMaterial,
    PlasticWireframeMaterial,
    PrincipledBSDFMaterial,
    PrincipledBSDFWireframeMaterial,
)
from blendify_core.ir.renderables import (
    CircleMesh,
    CubeMesh,
    CurveBezier,
    CylinderMesh,
    EllipsoidNURBS,
    Mesh,
    PlaneMesh,
    PointCloud,
    SphereNURBS,
)
from blendify_core.ir.scene import Scene
from blendify_core.pipeline.capabilities import Capability
from blendify_core.pipeline.changes import SceneChanges
from blendify_core.pipeline.effects import analyse_effects
from blendify_core.pipeline.settings import RenderSettings, resolve_settings
from blendify_core.pipeline.translator import EXACT, TranslationContext, Translator, handles

from .materials import ALBEDO_AOV, MaterialBuilder
from .session import BPY_LOCK, BuiltScene, _Entry, bpy_module, capture_output, engine_errors, factory_reset, generation

__all__ = [
    "ALBEDO_AOV",
    "BuiltScene",
    "ColorFeed",
    "CyclesTranslator",
    "apply_cycles_settings",
    "apply_engine_settings",
    "build_scene",
    "check_cycles_settings",
]

_COLOR_ATTR = "bf_color_{}"
_RADIUS_ATTR = "bf_radius"
#: material parameters read through the mesh's UVs
_MAPS = ("roughness_map", "metallic_map", "normal_map")
#: object types ``attach_blend`` parses into the IR (rendered from the IR) -- every other renderable
#: type (volumes, hair curves, grease pencil, ...) is linked from the attached file itself
_PARSED_TYPES = ("MESH", "CURVE", "SURFACE", "META", "FONT", "LIGHT", "CAMERA", "EMPTY", "POINTCLOUD")


def _exact(note: str) -> Capability:
    """An exact feature with a note saying how."""
    return Capability("exact", note)


# ---------------------------------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------------------------------


def _recentre(vertices: np.ndarray, entry: _Entry) -> np.ndarray:
    """Move the object-space origin to the bounding-box centre (in float64) before going to float32, so
    far-away geometry keeps its precision; the centre is kept in ``entry.offset`` and folded into the
    object matrix by :func:`_object_matrix`."""
    v = np.asarray(vertices, dtype=np.float64)
    if len(v) == 0:
        entry.offset = None
        return v.astype(np.float32).reshape(-1, 3)
    # any centre near the data does the job: take it from at most ~4096 samples (a full min/max over
    # millions of (N, 3) rows costs ~0.1 s)
    sample = v[:: max(1, len(v) // 4096)]
    lo, hi = sample.min(axis=0), sample.max(axis=0)
    c = (lo + hi) / 2.0
    if not np.any(np.abs(c) > 1e-3 * max(1.0, float((hi - lo).max()) / 2.0)):
        entry.offset = None
        return np.ascontiguousarray(v, dtype=np.float32)
    entry.offset = c
    return np.ascontiguousarray(v - c, dtype=np.float32)


def _object_matrix(r: Any, entry: _Entry) -> np.ndarray:
    m = r.matrix_world
    if entry.offset is None:
        return m
    m = m.copy()
    m[:3, 3] = m[:3, :3] @ entry.offset + m[:3, 3]
    return m


def _set_matrix(obj: Any, m: np.ndarray) -> None:
    import mathutils  # Blender's module: importable once bpy is

    obj.matrix_world = mathutils.Matrix(np.asarray(m, dtype=np.float64).tolist())


def new_mesh(
    name: str,
    vertices: np.ndarray,
    faces: np.ndarray,
    smooth: bool = False,
    normals: np.ndarray | None = None,
    corner_uv: np.ndarray | None = None,
    material_index: np.ndarray | None = None,
) -> Any:
    """A triangle mesh from numpy arrays with bulk ``foreach_set`` (vertices float32 (N, 3), faces
    (F, 3), optional per-vertex custom normals, per-corner UVs (F, 3, 2), material index per face)."""
    bpy = bpy_module()
    me = bpy.data.meshes.new(name)
    n, f = len(vertices), len(faces)
    me.vertices.add(n)
    me.vertices.foreach_set("co", np.ascontiguousarray(vertices, dtype=np.float32).ravel())
    if f:
        me.loops.add(3 * f)
        me.loops.foreach_set("vertex_index", np.ascontiguousarray(faces, dtype=np.int32).ravel())
        me.polygons.add(f)
        me.polygons.foreach_set("loop_start", np.arange(0, 3 * f, 3, dtype=np.int32))
    me.update(calc_edges=True)
    if f:
        # new faces are smooth (no "sharp_face" attribute); flat = sharp_face on every face (one bulk
        # write; Mesh.shade_flat() costs 0.12 s on 330k faces)
        if not smooth:
            sharp = me.attributes.new("sharp_face", "BOOLEAN", "FACE")
            sharp.data.foreach_set("value", np.ones(f, dtype=bool))
        if material_index is not None:
            me.polygons.foreach_set("material_index", np.ascontiguousarray(material_index, dtype=np.int32))
        if corner_uv is not None:
            uv = me.uv_layers.new(name="UVMap")
            uv.data.foreach_set("uv", np.ascontiguousarray(corner_uv, dtype=np.float32).ravel())
        if smooth and normals is not None:
            # the IR's vertex normals as Blender's custom normals (a point-domain "custom_normal" attribute,
            # one bulk write), so that Cycles shades with the normals every backend gets
            custom = me.attributes.new("custom_normal", "FLOAT_VECTOR", "POINT")
            custom.data.foreach_set("vector", np.ascontiguousarray(normals, dtype=np.float32).ravel())
    return me


def _material_value_key(m: Any) -> tuple[Any, ...]:
    """A hashable key of a material's class and values (texture maps by identity)."""
    items = []
    for k in sorted(m.parameter_names()):
        v = getattr(m, k)
        if v is not None and not isinstance(v, (int, float, str, tuple)):
            v = ("texture", id(v))
        items.append((k, v))
    return (type(m).__name__, m.color_space, tuple(items))


def _uses_maps(m: Any) -> bool:
    """Whether a material reads texture maps through the UVs (only the Principled family has maps)."""
    return any(getattr(m, k, None) is not None for k in _MAPS)


def _radius_key(r: Any) -> str:
    return repr(r.radius.tolist() if isinstance(r.radius, np.ndarray) else r.radius)


def _rgba(rgb: np.ndarray) -> np.ndarray:
    out = np.ones(rgb.shape[:2] + (4,), dtype=np.float32)
    out[..., :3] = rgb
    return out


def _all_ids(bpy: Any) -> list[Any]:
    out: list[Any] = []
    for name in dir(bpy.data):
        coll = getattr(bpy.data, name, None)
        if isinstance(coll, bpy.types.bpy_prop_collection) and name not in ("window_managers", "screens", "workspaces"):
            try:
                out.extend(i for i in coll if isinstance(i, bpy.types.ID))
            except TypeError:
                continue
    return out


def check_scene(scene: Any) -> None:
    """Refuse what is not a Scene, or a scene without a camera (InvalidSceneError)."""
    if not isinstance(scene, Scene):
        raise InvalidSceneError(f"scene: expected a blendify_core.Scene, got {type(scene).__name__}")
    if scene.camera is None:
        raise InvalidSceneError("scene.camera: the scene has no camera; call scene.set_perspective_camera(...) first")


@dataclass
class ColorFeed:
    """How a colour source gives a material its base colour (what a colour handler returns).

    ``nodes(nt, name, entry)`` adds the nodes to a material's node tree and returns (colour, alpha), each
    a node output socket or a constant (images are named after the material and owned by ``entry``);
    ``vertex_rgba`` (per-vertex linear RGBA) is written by the renderable as the colour attribute
    ``bf_color_<slot>``; materials fed by an equal ``share_key`` are built once per scene; ``needs_uv``:
    the colour is read through the mesh's UVs."""

    nodes: Callable[[Any, str, Any], tuple[Any, Any]]
    vertex_rgba: np.ndarray | None = None
    share_key: tuple[Any, ...] | None = None
    needs_uv: bool = False


@dataclass
class MaterialTarget:
    """Where a material handler puts its material: the datablock ``name``, the ``entry`` owning it, and
    ``emission_from_color`` > 0 to make the surface emit its own colour (point-cloud emission)."""

    name: str
    entry: _Entry
    emission_from_color: float = 0.0


# ---------------------------------------------------------------------------------------------------
# the translator
# ---------------------------------------------------------------------------------------------------


class CyclesTranslator(Translator):
    """Translates one IR scene into the bpy scene of ``built``: one handler per IR type (see the module
    docstring for where each lives). ``share=False`` builds every primitive mesh and material for its own
    object (the benchmarks time single renderables that way)."""

    backend = "cycles"
    #: capabilities not tied to one IR type
    extra_capabilities: ClassVar[dict[str, Capability]] = {
        "object.no_shadow": EXACT,  # _renderable: the object's shadow-ray visibility
        "light.no_shadow": EXACT,  # _light: the light's use_shadow
        # the outputs: render.py's passes
        "output.rgb": EXACT,
        "output.depth": _exact("Cycles Z pass (one sample per pixel, not anti-aliased)"),
        "output.normal": EXACT,
        "output.albedo": _exact("material colour input through a shader AOV"),
        "output.instance": _exact("object index pass (not anti-aliased)"),
    }
    check_scene = staticmethod(check_scene)

    def __init__(
        self,
        built: BuiltScene,
        settings: RenderSettings,
        device: str = "CPU",
        compute_device_type: str = "",
        share: bool = True,
    ) -> None:
        self.built = built
        self.sc = built.bscene
        self.settings = settings
        self.device = device
        self.compute_device_type = compute_device_type
        self.share = share
        self.mb = MaterialBuilder()
        self.plan: FilePlan | None = None

    # -- the walk ----------------------------------------------------------------------------------
    def translate(self, scene: Scene, changes: SceneChanges, ctx: TranslationContext) -> dict[str, Any]:
        """Bring ``self.built`` in line with ``scene`` given what changed; returns what was done."""
        built = self.built
        stats: dict[str, Any] = {"built": 0, "moved": 0, "removed": 0, "lights_rebuilt": False}
        for uid in changes.removed:
            entry = built.entries.pop(uid, None)
            if entry is not None:
                entry.remove()
                stats["removed"] += 1
        rebuilt, moved = set(changes.rebuilt), set(changes.moved)
        reindex = bool(changes.order or changes.added or changes.removed)
        # attached objects still exactly as parsed render from their file (original materials, modifiers)
        plan = self.plan = file_plan(scene, self.settings.outputs)
        for i, r in enumerate(scene.renderables):
            entry = built.entries.get(r.uid)
            if r.uid in plan.renderables:
                if entry is not None:
                    built.entries.pop(r.uid).remove()
                continue
            if entry is not None and r.uid in rebuilt:
                entry.remove()
                entry = None
            if entry is None:
                built.entries[r.uid] = self._renderable(r, i, ctx)
                stats["built"] += 1
                continue
            obj = entry.objects[0]
            if reindex and obj.pass_index != i + 1:  # an RNA write tags the depsgraph: only when it changed
                obj.pass_index = i + 1
            if r.uid in moved:
                _set_matrix(obj, _object_matrix(r, entry))
                stats["moved"] += 1
        if changes.attachments or (changes.first and scene.attachments):
            built.attached.remove()
            built.attached = _Entry()
            built.file_contents = []
            for a in scene.attachments:
                self.dispatch(a, ctx)
            stats["attached_blends"] = len(scene.attached_blends)
        self._apply_file_plan(scene, plan, stats)
        limits = _ir_limits(scene, plan)
        if limits:
            stats["ir_limits"] = limits
        file_lights = frozenset(plan.lights)
        if changes.first or changes.lights or changes.attachments or file_lights != built.file_lights:
            built.lights.remove()
            built.lights = _Entry()
            for i, light in enumerate(scene.lights):
                if light.uid not in file_lights:
                    self._light(light, i, ctx)
            built.file_lights = file_lights
            stats["lights_rebuilt"] = True
        if changes.first or changes.world or changes.attachments or plan.world != built.file_world:
            built.world.remove()
            world = self._file_world(plan)
            built.world = _Entry() if world is not None else self._world(scene.lights, ctx)
            if world is not None:
                self.sc.world = world
            built.file_world = plan.world if world is not None else None
            stats["world_rebuilt"] = True
        self.dispatch(scene.camera, ctx)  # every time: cheap, and camera objects come and go between renders
        built.engine_settings = apply_engine_settings(
            self.sc, self.settings, scene, self.device, self.compute_device_type
        )
        built.instance_tags = [r.tag for r in scene.renderables]
        if ctx.ignored:
            stats["ignored"] = list(ctx.ignored)
        return stats

    # -- attached files: what renders from the file itself ----------------------------------------
    def _apply_file_plan(self, scene: Scene, plan: FilePlan, stats: dict[str, Any]) -> None:
        """Show the attached files' objects that are still as parsed, hide the others (see blendfile.linking);
        with the instance output their pass indices are the IR renderables' (else the file's own)."""
        contents = self.built.file_contents
        if not contents:
            return
        index_of: dict[str, int] | None = None
        if "instance" in self.settings.outputs:
            index_of = {}
            for i, r in enumerate(scene.renderables):
                if r.uid in plan.renderables:
                    group = plan.groups.get(r.uid)
                    if group is not None:
                        index_of[group] = i + 1
        for content in contents:
            content.apply(plan, index_of)
        stats["from_file"] = {
            "renderables": len(plan.renderables),
            "lights": len(plan.lights),
            "world": plan.world is not None,
        }
        if plan.reasons:
            stats["from_file"]["ir_because"] = list(plan.reasons)

    def _file_world(self, plan: FilePlan) -> Any:
        """The attached file's own world when the plan uses it (and the file has one), else None."""
        if plan.world is None:
            return None
        for content in self.built.file_contents:
            if (content.path, content.scene_name) == plan.world:
                return content.world
        return None

    def _renderable(self, r: Any, index: int, ctx: TranslationContext) -> _Entry:
        """The datablocks of one renderable: its handler builds the object, placed and linked here."""
        entry = _Entry()
        name = f"bf_{index}_{r.tag}"[:60]
        obj = self.dispatch(r, ctx, entry, name)
        entry.objects.append(obj)
        self.sc.collection.objects.link(obj)
        _set_matrix(obj, _object_matrix(r, entry))
        obj.pass_index = index + 1
        obj.visible_shadow = bool(r.emit_shadows)
        return entry

    # -- renderables ---------------------------------------------------------------------------------
    @handles(
        Mesh,
        features={
            "mesh": EXACT,
            "mesh.smooth": _exact("the IR's angle-weighted vertex normals as custom normals"),
            "mesh.faces_material": EXACT,
        },
    )
    def mesh(self, r: Mesh, ctx: TranslationContext, entry: _Entry, name: str) -> Any:
        feeds = self._feeds(r, ctx)
        corner_uv = r.triangle_uvs()
        if corner_uv is None and (any(f.needs_uv for f in feeds) or any(_uses_maps(m) for m in r.materials)):
            raise InvalidSceneError(
                f"uv_map: renderable {r.tag!r} uses a texture but has no UV map (pass uv_map= to add_mesh)"
            )
        normals = r.vertex_normals() if r.smooth else None  # the IR's rule, not Blender's own computation
        return self._mesh_object(
            r, name, entry, ctx, feeds, r.vertices, r.faces, r.smooth, normals, corner_uv, r.faces_material
        )

    @handles(
        PointCloud,
        features={
            "pointcloud": _exact("native Cycles points (Geometry Nodes Mesh to Points)"),
            "pointcloud.vertex_colors": EXACT,
            "pointcloud.emission": EXACT,
        },
    )
    def pointcloud(self, r: PointCloud, ctx: TranslationContext, entry: _Entry, name: str) -> Any:
        """Native Cycles points: a vertex-only mesh + Geometry Nodes (Mesh to Points, radius from an
        attribute, Set Material)."""
        bpy = bpy_module()
        v32 = _recentre(r.vertices, entry)
        me = entry.add("meshes", bpy.data.meshes.new(name))
        n = len(v32)
        me.vertices.add(n)
        me.vertices.foreach_set("co", v32.ravel())
        radii = r.radii().astype(np.float32)
        per_point_radius = np.ndim(r.point_size) != 0
        if per_point_radius and n:
            a = me.attributes.new(_RADIUS_ATTR, "FLOAT", "POINT")
            a.data.foreach_set("value", radii)
        feed = self.dispatch(r.colors_list[0], ctx, 0)
        if feed.vertex_rgba is not None and n:
            ca = me.attributes.new(_COLOR_ATTR.format(0), "FLOAT_COLOR", "POINT")
            ca.data.foreach_set("color", np.ascontiguousarray(feed.vertex_rgba, dtype=np.float32).ravel())
        me.update()
        target = MaterialTarget(f"{name}_m0", entry, emission_from_color=r.particle_emission_strength)
        mat = self.dispatch(r.materials[0], ctx, feed, target)
        me.materials.append(mat)
        ng = entry.add("node_groups", bpy.data.node_groups.new(f"{name}_points", "GeometryNodeTree"))
        ng.interface.new_socket(name="Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
        ng.interface.new_socket(name="Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
        gi = ng.nodes.new("NodeGroupInput")
        go = ng.nodes.new("NodeGroupOutput")
        m2p = ng.nodes.new("GeometryNodeMeshToPoints")
        m2p.mode = "VERTICES"
        if per_point_radius:
            na = ng.nodes.new("GeometryNodeInputNamedAttribute")
            na.data_type = "FLOAT"
            na.inputs["Name"].default_value = _RADIUS_ATTR
            ng.links.new(na.outputs["Attribute"], m2p.inputs["Radius"])
        else:
            m2p.inputs["Radius"].default_value = float(radii[0]) if n else 0.0
        sm = ng.nodes.new("GeometryNodeSetMaterial")
        sm.inputs["Material"].default_value = mat
        ng.links.new(gi.outputs[0], m2p.inputs["Mesh"])
        ng.links.new(m2p.outputs["Points"], sm.inputs["Geometry"])
        ng.links.new(sm.outputs["Geometry"], go.inputs[0])
        obj = bpy.data.objects.new(name, me)
        mod = obj.modifiers.new("bf_points", "NODES")
        mod.node_group = ng
        return obj

    @handles(
        CubeMesh,
        CircleMesh,
        CylinderMesh,
        features={"primitive.cube": EXACT, "primitive.circle": EXACT, "primitive.cylinder": EXACT},
    )
    def primitive(self, r: Any, ctx: TranslationContext, entry: _Entry, name: str) -> Any:
        return self._primitive(r, ctx, entry, name, self._mesh_primitive_key(r))

    @handles(PlaneMesh, features={"primitive.plane": EXACT, "shadow_catcher": EXACT})
    def plane(self, r: PlaneMesh, ctx: TranslationContext, entry: _Entry, name: str) -> Any:
        obj = self._primitive(r, ctx, entry, name, self._mesh_primitive_key(r))
        # a catcher shows only the shadows it receives: not in reflections, refractions or bounced light
        # (blendify 2.1's catcher, Blender's shadow catcher with those ray visibilities off)
        obj.is_shadow_catcher = bool(r.shadow_catcher)
        for ray in ("visible_glossy", "visible_diffuse", "visible_transmission", "visible_volume_scatter"):
            setattr(obj, ray, not r.shadow_catcher)
        return obj

    @handles(
        SphereNURBS,
        features={"primitive.sphere": _exact("the IR's shared tessellation (64x32 UV sphere, exact normals)")},
    )
    def sphere(self, r: SphereNURBS, ctx: TranslationContext, entry: _Entry, name: str) -> Any:
        return self._primitive(r, ctx, entry, name, ("SphereNURBS", _radius_key(r), 1), force_smooth=True)

    @handles(
        EllipsoidNURBS, features={"primitive.ellipsoid": _exact("the IR's shared tessellation (64x32, exact normals)")}
    )
    def ellipsoid(self, r: EllipsoidNURBS, ctx: TranslationContext, entry: _Entry, name: str) -> Any:
        return self._primitive(r, ctx, entry, name, ("EllipsoidNURBS", _radius_key(r), 1), force_smooth=True)

    @handles(
        CurveBezier,
        features={
            "primitive.curve": _exact(
                "the IR's tessellation (tube along the polyline, flat caps), the mesh Mitsuba and pyrender render"
            )
        },
    )
    def curve(self, r: CurveBezier, ctx: TranslationContext, entry: _Entry, name: str) -> Any:
        """A tube through the keypoints: the IR's tessellation with its normals (Blender's own bevel of a POLY
        spline gave the same surface to 1e-4 but normals 2.8 deg (q99) off the other engines')."""
        return self._primitive_mesh(r, name, entry, ctx, self._feeds(r, ctx), False)

    # -- renderable helpers ------------------------------------------------------------------------
    def _feeds(self, r: Any, ctx: TranslationContext) -> list[ColorFeed]:
        """The colour feeds of ``r``'s material slots (from the colour handlers)."""
        return [self.dispatch(c, ctx, i) for i, c in enumerate(r.colors_list)]

    def _materials(
        self, r: Any, name: str, entry: _Entry, ctx: TranslationContext, feeds: list[ColorFeed]
    ) -> list[Any]:
        """The bpy materials of ``r``'s slots. Materials fed by a shareable colour (uniform) are built once
        per scene for each (material values, colour) and owned by ``built.shared``; others get their own."""
        built = self.built
        out = []
        for i, (m, feed) in enumerate(zip(r.materials, feeds)):
            if self.share and feed.share_key is not None:
                key = (_material_value_key(m), feed.share_key)
                hit = built.shared_materials.get(key)
                if hit is None:
                    mat = self.dispatch(
                        m, ctx, feed, MaterialTarget(f"bf_mat_{len(built.shared_materials)}", built.shared)
                    )
                    # the IR material is kept alive with the cache: the ids of its texture maps stay unique
                    built.shared_materials[key] = hit = (m, mat)
                out.append(hit[1])
            else:
                out.append(self.dispatch(m, ctx, feed, MaterialTarget(f"{name}_m{i}", entry)))
        return out

    def _mesh_object(
        self,
        r: Any,
        name: str,
        entry: _Entry,
        ctx: TranslationContext,
        feeds: list[ColorFeed],
        verts: np.ndarray,
        faces: np.ndarray,
        smooth: bool,
        normals: np.ndarray | None,
        corner_uv: np.ndarray | None,
        mat_index: np.ndarray | None,
        materials: bool = True,
    ) -> Any:
        bpy = bpy_module()
        t0 = time.perf_counter()
        v32 = _recentre(verts, entry)
        me = entry.add("meshes", new_mesh(name, v32, faces, smooth, normals, corner_uv, mat_index))
        t1 = time.perf_counter()
        for i, feed in enumerate(feeds):
            if feed.vertex_rgba is not None:
                ca = me.color_attributes.new(_COLOR_ATTR.format(i), "FLOAT_COLOR", "POINT")
                ca.data.foreach_set("color", np.ascontiguousarray(feed.vertex_rgba, dtype=np.float32).ravel())
        t2 = time.perf_counter()
        if materials:
            for mat in self._materials(r, name, entry, ctx, feeds):
                me.materials.append(mat)
        t3 = time.perf_counter()
        entry.timings.update(geometry=t1 - t0, vertex_colors=t2 - t1, materials=t3 - t2)
        return bpy.data.objects.new(name, me)

    @staticmethod
    def _mesh_primitive_key(r: Any) -> tuple[Any, ...]:
        params = tuple(sorted((k, repr(v)) for k, v in r._params().items()))
        fm = r._faces_material_poly
        return (type(r).__name__, params, r.smooth, None if fm is None else tuple(fm.tolist()), len(r.materials))

    def _primitive(
        self,
        r: Any,
        ctx: TranslationContext,
        entry: _Entry,
        name: str,
        key: tuple[Any, ...],
        force_smooth: bool = False,
    ) -> Any:
        """A primitive from the IR's tessellation (``to_mesh``). Its mesh is shared with every other primitive
        of the same shape (``key``: one tessellation, one upload); its materials sit in object-linked slots."""
        bpy = bpy_module()
        feeds = self._feeds(r, ctx)
        if not self.share:
            return self._primitive_mesh(r, name, entry, ctx, feeds, force_smooth)
        built = self.built
        cached = built.shared_meshes.get(key)
        if cached is None:
            tmp = _Entry()
            obj = self._primitive_mesh(
                r, f"bf_shared_{len(built.shared_meshes)}_{type(r).__name__}", tmp, ctx, feeds, force_smooth, False
            )
            me = obj.data
            bpy.data.objects.remove(obj)
            for _ in r.materials:
                me.materials.append(None)
            built.shared.data.append(("meshes", me))
            built.shared_meshes[key] = cached = (me, tmp.offset)
            entry.timings.update(tmp.timings)
        me, entry.offset = cached
        obj = bpy.data.objects.new(name, me)
        for i, mat in enumerate(self._materials(r, name, entry, ctx, feeds)):
            slot = obj.material_slots[i]
            slot.link = "OBJECT"
            slot.material = mat
        return obj

    def _primitive_mesh(
        self,
        r: Any,
        name: str,
        entry: _Entry,
        ctx: TranslationContext,
        feeds: list[ColorFeed],
        force_smooth: bool,
        materials: bool = True,
    ) -> Any:
        tm = r.to_mesh()
        smooth = bool(tm.smooth or force_smooth)
        mat_index = None
        fm = getattr(r, "_faces_material_poly", None)
        if fm is not None and tm.face_polygon is not None:
            mat_index = fm[tm.face_polygon]
        normals = tm.normals if smooth else None
        return self._mesh_object(
            r, name, entry, ctx, feeds, tm.vertices, tm.faces, smooth, normals, tm.uv, mat_index, materials
        )

    # -- colour sources ----------------------------------------------------------------------------
    @handles(UniformColors)
    def uniform_colors(self, c: UniformColors, ctx: TranslationContext, slot: int) -> ColorFeed:
        rgba = tuple(float(x) for x in c.linear_rgba)
        return ColorFeed(lambda nt, name, entry: (rgba, rgba[3]), share_key=rgba)

    @handles(VertexColors, features={"mesh.vertex_colors": EXACT})
    def vertex_colors(self, c: VertexColors, ctx: TranslationContext, slot: int) -> ColorFeed:
        attribute = _COLOR_ATTR.format(slot)
        return ColorFeed(
            lambda nt, name, entry: self.mb.attribute_color(nt, attribute, c.has_alpha), vertex_rgba=c.linear_rgba
        )

    @handles(TextureColors, features={"mesh.texture": EXACT})
    def texture_colors(self, c: TextureColors, ctx: TranslationContext, slot: int) -> ColorFeed:
        def nodes(nt: Any, name: str, entry: _Entry) -> tuple[Any, Any]:
            t0 = time.perf_counter()
            if c.texture.dtype == np.uint8:
                cs = "sRGB" if c.color_space == "srgb" else "Linear Rec.709"
                img = self.mb.image_from_uint8(f"{name}_tex", c.texture, cs, entry)
            else:
                img = self.mb.image_from_array(f"{name}_tex", c.linear_rgba_image(), "Linear Rec.709", entry)
            entry.timings["texture_upload"] = entry.timings.get("texture_upload", 0.0) + time.perf_counter() - t0
            return self.mb.image_color(nt, img, c.interpolation, c.has_alpha)

        return ColorFeed(nodes, needs_uv=True)

    @handles(FileTextureColors, features={"mesh.file_texture": EXACT})
    def file_texture_colors(self, c: FileTextureColors, ctx: TranslationContext, slot: int) -> ColorFeed:
        def nodes(nt: Any, name: str, entry: _Entry) -> tuple[Any, Any]:
            cs = "sRGB" if c.color_space == "srgb" else "Linear Rec.709"
            img = self.mb.image_from_file(f"{name}_tex", c.texture_path, cs, entry)
            return self.mb.image_color(nt, img, c.interpolation, c.has_alpha)

        return ColorFeed(nodes, needs_uv=True)

    # -- materials ---------------------------------------------------------------------------------
    @handles(
        PrincipledBSDFMaterial,
        DiffuseMaterial,
        MetalMaterial,
        PlasticMaterial,
        features={
            "material.principled": EXACT,
            "material.diffuse_only": EXACT,
            "material.metallic": EXACT,
            "material.transmission": EXACT,
            "material.coat": EXACT,
            "material.sheen": EXACT,
            "material.subsurface": EXACT,
            "material.emission": EXACT,
            "material.alpha": EXACT,
            "material.roughness_map": EXACT,
            "material.metallic_map": EXACT,
            "material.normal_map": EXACT,
        },
    )
    def principled(self, m: Any, ctx: TranslationContext, feed: ColorFeed, target: MaterialTarget) -> Any:
        """A Principled BSDF with every input of the material, coloured by the feed."""
        mat, nt, out = self.mb.new_material(target.name, target.entry)
        color, color_alpha = feed.nodes(nt, target.name, target.entry)
        alpha = self.mb.alpha(nt, m.alpha, color_alpha)
        bsdf = self.mb.principled(nt, target.name, m, color, alpha, target.entry, target.emission_from_color)
        self.mb.finish(nt, out, bsdf.outputs["BSDF"], color)
        return mat

    @handles(
        PrincipledBSDFWireframeMaterial,
        PlasticWireframeMaterial,
        MetalWireframeMaterial,
        features={"material.wireframe": EXACT},
    )
    def wireframe(self, m: Any, ctx: TranslationContext, feed: ColorFeed, target: MaterialTarget) -> Any:
        """The Principled surface with the triangle edges drawn over it (the albedo shows the wire too)."""
        mat, nt, out = self.mb.new_material(target.name, target.entry)
        color, color_alpha = feed.nodes(nt, target.name, target.entry)
        alpha = self.mb.alpha(nt, m.alpha, color_alpha)
        bsdf = self.mb.principled(nt, target.name, m, color, alpha, target.entry, target.emission_from_color)
        surface, albedo = self.mb.wireframe(nt, target.name, m, bsdf.outputs["BSDF"], color, alpha, target.entry)
        self.mb.finish(nt, out, surface, albedo)
        return mat

    @handles(GlossyBSDFMaterial, features={"material.glossy": EXACT})
    def glossy(self, m: GlossyBSDFMaterial, ctx: TranslationContext, feed: ColorFeed, target: MaterialTarget) -> Any:
        """Blender's Glossy BSDF tinted by the feed's colour."""
        mat, nt, out = self.mb.new_material(target.name, target.entry)
        color, color_alpha = feed.nodes(nt, target.name, target.entry)
        alpha = self.mb.alpha(nt, m.alpha, color_alpha)
        surface = self.mb.glossy(nt, m, color, alpha, target.emission_from_color)
        self.mb.finish(nt, out, surface, color)
        return mat

    # -- lights ------------------------------------------------------------------------------------
    def _light(self, light: Any, index: int, ctx: TranslationContext) -> None:
        """One light: its handler makes the light data; strength, colour and shadows are common."""
        bpy = bpy_module()
        entry = self.built.lights
        name = f"bf_light_{index}_{light.tag}"[:60]
        data = self.dispatch(light, ctx, name)
        entry.add("lights", data)
        data.energy = float(light.strength)
        data.color = tuple(float(x) for x in light.linear_color)
        data.use_shadow = bool(light.use_shadow)
        data.exposure = 0.0
        data.use_temperature = False
        obj = bpy.data.objects.new(name, data)
        obj.visible_camera = False
        self.sc.collection.objects.link(obj)
        _set_matrix(obj, light.matrix_world)
        entry.objects.append(obj)

    @handles(
        PointLight,
        features={
            "light.point": EXACT,
            "light.point.soft": _exact("sphere light, soft falloff off (matches a sphere emitter)"),
        },
    )
    def point_light(self, light: PointLight, ctx: TranslationContext, name: str) -> Any:
        data = bpy_module().data.lights.new(name, "POINT")
        data.shadow_soft_size = light.shadow_soft_size
        data.use_soft_falloff = False
        return data

    @handles(
        SpotLight, features={"light.spot": EXACT, "light.spot.blend": _exact("Blender's own smoothstep cone edge")}
    )
    def spot_light(self, light: SpotLight, ctx: TranslationContext, name: str) -> Any:
        data = bpy_module().data.lights.new(name, "SPOT")
        data.shadow_soft_size = light.shadow_soft_size
        data.use_soft_falloff = False
        data.spot_size = light.spot_size
        data.spot_blend = light.spot_blend
        return data

    @handles(SunLight, features={"light.sun": EXACT, "light.sun.soft": EXACT})
    def sun_light(self, light: SunLight, ctx: TranslationContext, name: str) -> Any:
        data = bpy_module().data.lights.new(name, "SUN")
        data.angle = light.angular_diameter
        return data

    @handles(AreaLight, features={"light.area": EXACT, "light.area.disk": EXACT})
    def area_light(self, light: AreaLight, ctx: TranslationContext, name: str) -> Any:
        data = bpy_module().data.lights.new(name, "AREA")
        data.shape = {"square": "SQUARE", "circle": "DISK", "rectangle": "RECTANGLE", "ellipse": "ELLIPSE"}[light.shape]
        data.size = light.size[0]
        data.size_y = light.size[1]
        data.normalize = True
        return data

    # -- world -------------------------------------------------------------------------------------
    def _world(self, lights: Any, ctx: TranslationContext) -> _Entry:
        """The world: background light plus the environment map, added; nothing else (the new World's
        0.05 grey is replaced, by black when neither is present)."""
        bpy = bpy_module()
        entry = _Entry()
        world = entry.add("worlds", bpy.data.worlds.new("bf_world"))
        self.sc.world = world
        nt = world.node_tree
        nt.nodes.clear()
        out = nt.nodes.new("ShaderNodeOutputWorld")
        out.target = "ALL"
        shaders = []
        for source in (lights.background, lights.environment):
            if source is not None:
                shader = self.dispatch(source, ctx, world, entry)
                if shader is not None:
                    shaders.append(shader)
        if not shaders:
            node = nt.nodes.new("ShaderNodeBackground")
            node.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
            node.inputs["Strength"].default_value = 0.0
            shaders.append(node.outputs[0])
        while len(shaders) > 1:
            add = nt.nodes.new("ShaderNodeAddShader")
            nt.links.new(shaders.pop(), add.inputs[0])
            nt.links.new(shaders.pop(), add.inputs[1])
            shaders.append(add.outputs[0])
        nt.links.new(shaders[0], out.inputs["Surface"])
        return entry

    @handles(BackgroundLight, features={"light.background": EXACT})
    def background_light(self, bg: BackgroundLight, ctx: TranslationContext, world: Any, entry: _Entry) -> Any:
        """A Background shader of the light's colour and strength (None when the strength is 0)."""
        if bg.strength <= 0:
            return None
        node = world.node_tree.nodes.new("ShaderNodeBackground")
        node.inputs["Color"].default_value = (*(float(x) for x in bg.linear_color), 1.0)
        node.inputs["Strength"].default_value = float(bg.strength)
        return node.outputs[0]

    @handles(EnvironmentMap, features={"light.environment": EXACT})
    def environment_map(self, env: EnvironmentMap, ctx: TranslationContext, world: Any, entry: _Entry) -> Any:
        """An equirectangular Environment Texture through a Mapping node that rotates directions by the
        inverse of the map's rotation (None when the strength is 0)."""
        import mathutils  # Blender's module: importable once bpy is

        if env.strength <= 0:
            return None
        nt = world.node_tree
        img = self.mb.image_from_array("bf_environment", _rgba(env.linear_rgb_image()), "Linear Rec.709", entry)
        tex = nt.nodes.new("ShaderNodeTexEnvironment")
        tex.image = img
        tex.interpolation = "Linear"
        tex.projection = "EQUIRECTANGULAR"
        coord = nt.nodes.new("ShaderNodeTexCoord")
        mapping = nt.nodes.new("ShaderNodeMapping")
        mapping.vector_type = "VECTOR"
        inv = np.asarray(env.rotation_matrix).T  # directions are rotated by the inverse of the map's rotation
        mapping.inputs["Rotation"].default_value = mathutils.Matrix(inv.tolist()).to_euler("XYZ")
        nt.links.new(coord.outputs["Generated"], mapping.inputs["Vector"])
        nt.links.new(mapping.outputs["Vector"], tex.inputs["Vector"])
        node = nt.nodes.new("ShaderNodeBackground")
        node.inputs["Strength"].default_value = float(env.strength)
        nt.links.new(tex.outputs["Color"], node.inputs["Color"])
        # importance map at the image's resolution (AUTOMATIC bakes 1024 wide: ~1.8 s per render here)
        world.cycles.sampling_method = "MANUAL"
        world.cycles.sample_map_resolution = int(min(max(img.size[0], 32), 1024))
        return node.outputs[0]

    # -- cameras (CONVENTIONS.md section 1.2/1.3) ----------------------------------------------------
    @handles(
        PerspectiveCamera, features={"camera.perspective": EXACT, "camera.anisotropic": _exact("pixel aspect ratio")}
    )
    def perspective_camera(self, cam: PerspectiveCamera, ctx: TranslationContext) -> None:
        """A pinhole: lens from fx with a 36 mm ``HORIZONTAL`` sensor, fx != fy through the pixel aspect."""
        fx, fy = cam.fx, cam.fy
        self._camera(
            cam,
            (max(fy / fx, 1.0), max(fx / fy, 1.0)),
            type="PERSP",
            lens_unit="MILLIMETERS",
            lens=cam.fx * 36.0 / cam.width,
        )

    @handles(OrthographicCamera, features={"camera.orthographic": EXACT})
    def orthographic_camera(self, cam: OrthographicCamera, ctx: TranslationContext) -> None:
        self._camera(cam, (1.0, 1.0), type="ORTHO", ortho_scale=cam.ortho_scale)

    def _camera(self, cam: Any, pixel_aspect: tuple[float, float], **data_fields: Any) -> None:
        """The camera object (made once per scene), its data (``data_fields`` first, then the sensor, the
        principal point through the shift and the clipping) and the render resolution."""
        bpy = bpy_module()
        built, sc = self.built, self.sc
        if not built.camera.objects:
            data = built.camera.add("cameras", bpy.data.cameras.new("bf_camera"))
            obj = bpy.data.objects.new("bf_camera", data)
            sc.collection.objects.link(obj)
            built.camera.objects.append(obj)
        obj = built.camera.objects[0]
        data = obj.data
        w, h = cam.width, cam.height
        pax, pay = pixel_aspect
        ycor = pay / pax
        for k, v in data_fields.items():
            setattr(data, k, v)
        data.sensor_fit = "HORIZONTAL"
        data.sensor_width = 36.0
        data.shift_x = (w / 2.0 - (cam.cx + 0.5)) / w
        data.shift_y = ((cam.cy + 0.5) - h / 2.0) * ycor / w
        data.clip_start, data.clip_end = cam.near, cam.far
        _set_matrix(obj, cam.matrix_world)
        sc.camera = obj
        r = sc.render
        r.resolution_x, r.resolution_y = w, h
        r.resolution_percentage = 100
        r.pixel_aspect_x, r.pixel_aspect_y = pax, pay

    # -- attached files ----------------------------------------------------------------------------
    @handles(Attachment)
    def attachment(self, a: Attachment, ctx: TranslationContext) -> None:
        """An attached .blend: its scenes are appended (through ``blendfile.append_blend_scenes``: auto-run
        off, Python drivers and text blocks removed) and the objects the IR could not represent (hair,
        volumes, ...) are linked into the render scene; everything appended is owned by ``built.attached``."""
        if a.format != "blend":
            ctx.ignore(a, f"Cycles renders attached .blend files only, not .{a.format}")
            return
        bpy = bpy_module()
        sc = self.sc
        before = {idb.as_pointer() for idb in _all_ids(bpy)}
        try:
            scenes, objects, _notes = append_blend_content(a.path)
            sname = self.plan.scenes.get(a.path) if self.plan is not None else None
            content = FileContent.link(sc, a.path, sname, scenes, objects) if sname is not None else None
            if content is not None:
                self.built.file_contents.append(content)
                return
            # no record of what was parsed (a scene file, a worker): only what the IR cannot represent
            for _name, bs in scenes:
                for obj in bs.objects:
                    if obj.type not in _PARSED_TYPES and obj.name not in sc.collection.objects:
                        sc.collection.objects.link(obj)
                        obj.pass_index = 0
        finally:
            self.built.attached.ids.extend(idb for idb in _all_ids(bpy) if idb.as_pointer() not in before and idb != sc)


# ---------------------------------------------------------------------------------------------------
# engine settings
# ---------------------------------------------------------------------------------------------------


#: RenderSettings.pixel_filter -> Cycles' pixel filter type
_PIXEL_FILTERS = {"box": "BOX", "gaussian": "GAUSSIAN", "blackman_harris": "BLACKMAN_HARRIS"}


def apply_engine_settings(
    sc: Any, settings: RenderSettings, scene: Scene, device: str = "CPU", compute_device_type: str = ""
) -> dict[str, Any]:
    """Set every Cycles setting explicitly from ``settings`` (and the effect analysis of ``scene`` when
    ``settings.effects``). Returns what was set (recorded in ``result.meta["engine_settings"]``)."""
    r, cy = sc.render, sc.cycles
    r.engine = "CYCLES"
    cy.device = device
    # without a colour output nothing needs lighting: one sample (the depth/index passes use one anyway)
    # and no bounces give the geometric passes from the same first hit, at a fraction of the cost
    geometry_only = "rgb" not in settings.outputs
    samples = 1 if geometry_only else int(settings.samples)
    cy.samples = samples
    cy.preview_samples = samples
    cy.seed = int(settings.seed)
    cy.use_animated_seed = False
    cy.use_denoising = bool(settings.denoise) and not geometry_only
    if settings.denoise:
        cy.denoiser = "OPENIMAGEDENOISE"
        cy.denoising_input_passes = "RGB_ALBEDO_NORMAL"
        cy.denoising_use_gpu = False
    # target_error is handled by the core (independent passes, CyclesBackend.path_tracer = True)
    cy.use_adaptive_sampling = bool(settings.adaptive) and not geometry_only
    cy.adaptive_threshold = 0.01
    cy.adaptive_min_samples = 0
    cy.time_limit = float(settings.time_limit) if settings.time_limit else 0.0
    cy.pixel_filter_type = _PIXEL_FILTERS[settings.pixel_filter]
    cy.filter_width = float(settings.pixel_filter_width)
    cy.sample_clamp_direct = float(settings.clamp_direct)
    cy.sample_clamp_indirect = float(settings.clamp_indirect)
    cy.blur_glossy = float(settings.filter_glossy)
    cy.use_light_tree = True
    mb = int(settings.max_bounces)
    # attached .blend content is not in the IR: the effect analysis cannot see it (volumes, hair, ...)
    attached = bool(getattr(scene, "attached_blends", None))
    eff = analyse_effects(scene) if settings.effects and not attached else None
    bounces = {
        "max_bounces": mb,
        "diffuse_bounces": settings.bounces("diffuse"),
        "glossy_bounces": settings.bounces("glossy"),
        "transmission_bounces": settings.bounces("transmission"),
        "volume_bounces": mb if attached else 0,
        "transparent_max_bounces": settings.bounces("transparent"),
        "caustics_reflective": True,
        "caustics_refractive": True,
    }
    if geometry_only:
        bounces = {k: (False if isinstance(v, bool) else 0) for k, v in bounces.items()}
    elif eff is not None:
        if not eff.indirect_diffuse:
            bounces["diffuse_bounces"] = 0
        if not eff.glossy:
            bounces["glossy_bounces"] = 0
        if not eff.transmission:
            bounces["transmission_bounces"] = 0
            bounces["caustics_refractive"] = False
        if not eff.caustics:
            bounces["caustics_reflective"] = False
            bounces["caustics_refractive"] = False
        if not eff.transparency:
            bounces["transparent_max_bounces"] = 0
    if not settings.caustics and not geometry_only:
        bounces["caustics_reflective"] = False
        bounces["caustics_refractive"] = False
    for k, v in bounces.items():
        setattr(cy, k, v)
    if settings.threads:
        r.threads_mode, r.threads = "FIXED", int(settings.threads)
    else:
        r.threads_mode = "AUTO"
    r.film_transparent = bool(settings.transparent_background)
    r.use_persistent_data = False
    r.dither_intensity = 0.0
    r.use_motion_blur = False
    vs = sc.view_settings
    vs.view_transform = "Standard"
    vs.look = "None"
    vs.exposure = 0.0
    vs.gamma = 1.0
    sc.display_settings.display_device = "sRGB"
    return {
        "engine": "CYCLES",
        "device": device,
        "compute_device_type": compute_device_type or "NONE",
        "samples": cy.samples,
        "seed": cy.seed,
        "denoise": cy.use_denoising,
        "adaptive": cy.use_adaptive_sampling,
        "adaptive_threshold": cy.adaptive_threshold if cy.use_adaptive_sampling else None,
        "time_limit": cy.time_limit,
        "pixel_filter": (cy.pixel_filter_type, cy.filter_width),
        "clamp_direct": cy.sample_clamp_direct,
        "clamp_indirect": cy.sample_clamp_indirect,
        "blur_glossy": cy.blur_glossy,
        **bounces,
        "threads": r.threads if settings.threads else "auto",
        "film_transparent": r.film_transparent,
        "view_transform": "Standard",
        "effects_used": eff is not None,
        "geometry_only": geometry_only,
    }


def _ir_limits(scene: Scene, plan: FilePlan) -> list[str]:
    """The approximations of the attached files whose parsed objects render (partly) from the IR parse."""
    out: list[str] = []
    for a in scene.attachments:
        sname = plan.scenes.get(a.path)
        from_ir = sname is None or bool(plan.hidden.get((a.path, sname))) or bool(plan.reasons)
        if from_ir:
            out.extend(a.ir_limits())
    return out


def check_cycles_settings(value: Any) -> dict[str, Any]:
    """The ``cycles_settings`` backend option validated: a dict of :data:`CYCLES_KEYS` -> value of the
    property's type (an empty dict for None)."""
    if value is None:
        return {}
    if not isinstance(value, dict):
        raise InvalidSceneError(f"cycles_settings: expected a dict of Cycles settings or None, got {value!r}")
    out: dict[str, Any] = {}
    for k, v in value.items():
        if k not in CYCLES_KEYS:
            raise InvalidSceneError(f"cycles_settings: unknown key {k!r}; expected names from {list(CYCLES_KEYS)}")
        if isinstance(v, bool) or not isinstance(v, (int, float, str)):
            if not (isinstance(v, bool) and k in ("caustics_reflective", "caustics_refractive", "use_light_tree")):
                raise InvalidSceneError(f"cycles_settings[{k!r}]: expected a number, a name or a bool, got {v!r}")
        out[k] = v
    return out


def apply_cycles_settings(built: BuiltScene, overrides: dict[str, Any]) -> None:
    """Set ``overrides`` (checked by :func:`check_cycles_settings`) on the built scene's Cycles settings after
    :func:`apply_engine_settings`; recorded in ``result.meta["engine_settings"]``."""
    cy = built.bscene.cycles
    for k, v in overrides.items():
        try:
            setattr(cy, k, v)
        except (TypeError, ValueError, AttributeError) as exc:
            raise InvalidSceneError(f"cycles_settings[{k!r}]: Blender refuses {v!r} ({exc})") from None
        built.engine_settings[k] = getattr(cy, k)


# ---------------------------------------------------------------------------------------------------
# whole-scene build (the .blend export) and single renderables (the benchmarks)
# ---------------------------------------------------------------------------------------------------


def build_scene(scene: Scene, settings: RenderSettings | None = None, reset: bool = True) -> BuiltScene:
    """Build the bpy scene for ``scene`` from scratch in the current bpy session (see the module doc).

    ``settings`` defaults to the "final" preset. With ``reset=True`` (default) bpy is first reset to an
    empty factory scene; with ``reset=False`` the objects are added to the current scene."""
    check_scene(scene)
    settings = settings or resolve_settings("final")
    bpy = bpy_module()
    with BPY_LOCK:
        if reset:
            factory_reset()
        built = BuiltScene(bscene=bpy.context.scene, generation=generation())
        with capture_output("build scene") as cap, engine_errors("building the scene", cap):
            built.stats = CyclesTranslator(built, settings).translate(
                scene, SceneChanges(first=True), TranslationContext()
            )
        return built


def _build_renderable(r: Any, index: int, sc: Any, mb: MaterialBuilder | None = None) -> _Entry:
    """The datablocks of one renderable in the bpy scene ``sc``, nothing shared with other objects (the
    benchmarks time this; ``entry.timings`` has the build steps)."""
    translator = CyclesTranslator(BuiltScene(bscene=sc), resolve_settings(), share=False)
    if mb is not None:
        translator.mb = mb
    return translator._renderable(r, index, TranslationContext())
