"""IR -> bpy translation for the Cycles backend.

Public entry points (reused by :mod:`blendify_blender.blendfile` for .blend export):

- ``build_scene(scene, settings=None, reset=True) -> BuiltScene``: build the whole bpy scene for a
  blendify-core :class:`~blendify_core.Scene` in the current bpy session (after a factory reset unless
  ``reset=False``): objects, meshes, point clouds, curves, materials, images, lights, world, camera and
  every Cycles setting. Returns the :class:`BuiltScene` that lists every datablock it created
  (``BuiltScene.remove()`` deletes them all). Call it while holding ``_runtime.BPY_LOCK``.
- :class:`Translator`: the cached, incremental version used by the backend: re-rendering after a camera
  or light change only updates those (meshes are rebuilt only when their geometry/appearance revision
  changes; a moved object only gets a new matrix).

Everything goes through the data API with bulk ``foreach_set`` of numpy arrays; no ``bpy.ops`` except
the factory reset. Conventions (camera, lights, colour) follow ``shared/docs/CONVENTIONS.md``.
"""

from __future__ import annotations

import time
import weakref
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from blendify_core.errors import InvalidSceneError, RenderError
from blendify_core.ir.colors import FileTextureColors, TextureColors, UniformColors, VertexColors
from blendify_core.ir.lights import AreaLight, PointLight, SpotLight, SunLight
from blendify_core.ir.renderables import (
    CurveBezier,
    EllipsoidNURBS,
    Mesh,
    MeshPrimitive,
    PlaneMesh,
    PointCloud,
    SphereNURBS,
)
from blendify_core.pipeline.effects import analyse_effects
from blendify_core.pipeline.settings import RenderSettings

from . import _runtime
from .materials import MaterialBuilder

__all__ = ["build_scene", "BuiltScene", "Translator", "ALBEDO_AOV", "camera_parameters"]

ALBEDO_AOV = "bf_albedo"
_COLOR_ATTR = "bf_color_{}"
_RADIUS_ATTR = "bf_radius"
_UV = "UVMap"


# ---------------------------------------------------------------------------------------------------
# datablock bookkeeping
# ---------------------------------------------------------------------------------------------------


@dataclass
class _Entry:
    """The datablocks of one renderable (or of the lights / world / camera)."""

    objects: list[Any] = field(default_factory=list)
    data: list[tuple[str, Any]] = field(default_factory=list)  # (bpy.data collection name, ID)
    key: tuple[Any, ...] = ()
    offset: np.ndarray | None = None  # object-space centre folded into the object matrix
    timings: dict[str, float] = field(default_factory=dict)  # seconds per build step (benchmarks)
    ids: list[Any] = field(default_factory=list)  # any other datablocks (removed with batch_remove)

    def add(self, collection: str, block: Any) -> Any:
        self.data.append((collection, block))
        return block

    def remove(self) -> None:
        bpy = _runtime.bpy_module()
        for obj in self.objects:
            try:
                bpy.data.objects.remove(obj, do_unlink=True)
            except ReferenceError:
                pass
        for coll, block in reversed(self.data):
            try:
                getattr(bpy.data, coll).remove(block, do_unlink=True)
            except (ReferenceError, RuntimeError):
                pass
        alive = []
        for block in self.ids:
            try:
                _ = block.name
                alive.append(block)
            except ReferenceError:
                pass
        if alive:
            bpy.data.batch_remove(alive)
        self.objects.clear()
        self.data.clear()
        self.ids.clear()


@dataclass
class BuiltScene:
    """The bpy scene built for one IR scene, with every datablock created for it."""

    bscene: Any
    entries: dict[int, _Entry] = field(default_factory=dict)  # renderable uid -> entry
    lights: _Entry = field(default_factory=_Entry)
    world: _Entry = field(default_factory=_Entry)
    camera: _Entry = field(default_factory=_Entry)
    compositor: _Entry = field(default_factory=_Entry)
    attached: _Entry = field(default_factory=_Entry)
    #: primitive meshes shared by every primitive of the same shape (materials linked per object)
    shared: _Entry = field(default_factory=_Entry)
    shared_meshes: dict[tuple[Any, ...], tuple[Any, np.ndarray | None]] = field(default_factory=dict)
    #: materials with a uniform colour, shared by every object using the same (material, colour)
    shared_materials: dict[tuple[Any, ...], tuple[Any, Any]] = field(default_factory=dict)
    generation: int = -1
    engine_settings: dict[str, Any] = field(default_factory=dict)
    instance_tags: list[str] = field(default_factory=list)

    @property
    def camera_object(self) -> Any:
        return self.camera.objects[0] if self.camera.objects else None

    def all_entries(self) -> list[_Entry]:
        return [
            *self.entries.values(),
            self.lights,
            self.world,
            self.camera,
            self.compositor,
            self.attached,
            self.shared,
        ]

    def remove(self) -> None:
        """Delete every datablock this scene created (objects first)."""
        for e in self.all_entries():
            e.remove()
        self.entries.clear()
        self.shared_meshes.clear()
        self.shared_materials.clear()


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
    import mathutils

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
    bpy = _runtime.bpy_module()
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
            uv = me.uv_layers.new(name=_UV)
            uv.data.foreach_set("uv", np.ascontiguousarray(corner_uv, dtype=np.float32).ravel())
        if smooth and normals is not None:
            me.normals_split_custom_set_from_vertices(np.ascontiguousarray(normals, dtype=np.float32))
    return me


# ---------------------------------------------------------------------------------------------------
# camera
# ---------------------------------------------------------------------------------------------------


def camera_parameters(cam: Any) -> dict[str, Any]:
    """Blender camera and render parameters for an IR camera (CONVENTIONS.md section 1.2/1.3)."""
    w, h = cam.width, cam.height
    if cam.kind == "perspective":
        fx, fy = cam.fx, cam.fy
        pax, pay = max(fy / fx, 1.0), max(fx / fy, 1.0)
    else:
        pax = pay = 1.0
    ycor = pay / pax
    p: dict[str, Any] = {
        "resolution": (w, h),
        "pixel_aspect": (pax, pay),
        "sensor_fit": "HORIZONTAL",
        "sensor_width": 36.0,
        "shift_x": (w / 2.0 - (cam.cx + 0.5)) / w,
        "shift_y": ((cam.cy + 0.5) - h / 2.0) * ycor / w,
        "clip_start": cam.near,
        "clip_end": cam.far,
    }
    if cam.kind == "perspective":
        p["type"] = "PERSP"
        p["lens"] = cam.fx * 36.0 / w
    else:
        p["type"] = "ORTHO"
        p["ortho_scale"] = cam.ortho_scale
    return p


def _apply_camera(built: BuiltScene, cam: Any) -> None:
    bpy = _runtime.bpy_module()
    sc = built.bscene
    if not built.camera.objects:
        data = built.camera.add("cameras", bpy.data.cameras.new("bf_camera"))
        obj = bpy.data.objects.new("bf_camera", data)
        sc.collection.objects.link(obj)
        built.camera.objects.append(obj)
    obj = built.camera.objects[0]
    data = obj.data
    p = camera_parameters(cam)
    data.type = p["type"]
    data.sensor_fit = p["sensor_fit"]
    data.sensor_width = p["sensor_width"]
    if p["type"] == "PERSP":
        data.lens_unit = "MILLIMETERS"
        data.lens = p["lens"]
    else:
        data.ortho_scale = p["ortho_scale"]
    data.shift_x, data.shift_y = p["shift_x"], p["shift_y"]
    data.clip_start, data.clip_end = p["clip_start"], p["clip_end"]
    _set_matrix(obj, cam.matrix_world)
    sc.camera = obj
    r = sc.render
    r.resolution_x, r.resolution_y = p["resolution"]
    r.resolution_percentage = 100
    r.pixel_aspect_x, r.pixel_aspect_y = p["pixel_aspect"]


# ---------------------------------------------------------------------------------------------------
# renderables
# ---------------------------------------------------------------------------------------------------


def _renderable_key(r: Any) -> tuple[Any, ...]:
    mats = tuple((id(m), m.revision) for m in r.materials)
    cols = tuple(id(c) for c in r.colors_list)
    return (type(r), r.revision("geometry"), r.revision("appearance"), mats, cols)


def _build_renderable(r: Any, index: int, sc: Any, mb: MaterialBuilder, built: BuiltScene | None = None) -> _Entry:
    entry = _Entry(key=_renderable_key(r))
    name = f"bf_{index}_{r.tag}"[:60]
    if isinstance(r, PointCloud):
        obj = _build_pointcloud(r, name, entry, mb)
    elif isinstance(r, CurveBezier):
        obj = _build_curve(r, name, entry, mb, built)
    elif built is not None and isinstance(r, (MeshPrimitive, SphereNURBS, EllipsoidNURBS)):
        obj = _build_shared_primitive(r, name, entry, mb, built)
    else:
        obj = _build_mesh_like(r, name, entry, mb, built=built)
    entry.objects.append(obj)
    sc.collection.objects.link(obj)
    _set_matrix(obj, _object_matrix(r, entry))
    obj.pass_index = index + 1
    obj.visible_shadow = bool(r.emit_shadows)
    if isinstance(r, PlaneMesh) and r.shadow_catcher:
        obj.is_shadow_catcher = True
    return entry


def _material_value_key(m: Any) -> tuple[Any, ...]:
    """A hashable key of a material's class and values (texture maps by identity)."""
    items = []
    for k, v in sorted(m.parameters().items()):
        if v is not None and not isinstance(v, (int, float, str, tuple)):
            v = ("texture", id(v))
        items.append((k, v))
    return (type(m).__name__, m.color_space, tuple(items))


def _materials_for(r: Any, name: str, entry: _Entry, mb: MaterialBuilder, built: BuiltScene | None = None) -> list[Any]:
    """The bpy materials of ``r``'s slots. (material, uniform colour) pairs are built once per scene and
    shared (owned by ``built.shared``); other colour sources get a material of their own."""
    out = []
    for i, (m, c) in enumerate(zip(r.materials, r.colors_list)):
        if built is not None and isinstance(c, UniformColors):
            key = (_material_value_key(m), tuple(float(x) for x in c.linear_rgba))
            hit = built.shared_materials.get(key)
            if hit is None:
                mat = mb.build(f"bf_mat_{len(built.shared_materials)}", m, c, slot=i, entry=built.shared)
                # the IR material is kept alive with the cache: the ids of its texture maps stay unique
                built.shared_materials[key] = hit = (m, mat)
            out.append(hit[1])
        else:
            out.append(mb.build(f"{name}_m{i}", m, c, slot=i, entry=entry))
    return out


def _build_mesh_like(
    r: Any, name: str, entry: _Entry, mb: MaterialBuilder, materials: bool = True, built: BuiltScene | None = None
) -> Any:
    bpy = _runtime.bpy_module()
    if isinstance(r, Mesh):
        verts, faces = r.vertices, r.faces
        smooth, normals = r.smooth, None
        corner_uv = r.triangle_uvs()
        mat_index = r.faces_material
        need_uv = any(isinstance(c, (TextureColors, FileTextureColors)) for c in r.colors_list) or any(
            m.parameters().get(k) is not None
            for m in r.materials
            for k in ("roughness_map", "metallic_map", "normal_map")
        )
        if need_uv and corner_uv is None:
            raise InvalidSceneError(
                f"uv_map: renderable {r.tag!r} uses a texture but has no UV map (pass uv_map= to add_mesh)"
            )
    else:
        tm = r.to_mesh()
        verts, faces, smooth = tm.vertices, tm.faces, bool(tm.smooth or isinstance(r, (SphereNURBS, EllipsoidNURBS)))
        normals = tm.normals if smooth else None
        corner_uv = tm.uv
        mat_index = None
        fm = getattr(r, "_faces_material_poly", None)
        if fm is not None and tm.face_polygon is not None:
            mat_index = fm[tm.face_polygon]
    t0 = time.perf_counter()
    v32 = _recentre(verts, entry)
    me = entry.add("meshes", new_mesh(name, v32, faces, smooth, normals, corner_uv, mat_index))
    t1 = time.perf_counter()
    for i, c in enumerate(r.colors_list):
        if isinstance(c, VertexColors):
            ca = me.color_attributes.new(_COLOR_ATTR.format(i), "FLOAT_COLOR", "POINT")
            ca.data.foreach_set("color", np.ascontiguousarray(c.linear_rgba, dtype=np.float32).ravel())
    t2 = time.perf_counter()
    if materials:
        for mat in _materials_for(r, name, entry, mb, built):
            me.materials.append(mat)
    t3 = time.perf_counter()
    entry.timings.update(geometry=t1 - t0, vertex_colors=t2 - t1, materials=t3 - t2)
    return bpy.data.objects.new(name, me)


def _primitive_key(r: Any) -> tuple[Any, ...]:
    if isinstance(r, MeshPrimitive):
        params = tuple(sorted((k, repr(v)) for k, v in r._params().items()))
        fm = getattr(r, "_faces_material_poly", None)
        return (type(r).__name__, params, r.smooth, None if fm is None else tuple(fm.tolist()), len(r.materials))
    radius = r.radius.tolist() if isinstance(r.radius, np.ndarray) else r.radius
    return (type(r).__name__, repr(radius), 1)


def _build_shared_primitive(r: Any, name: str, entry: _Entry, mb: MaterialBuilder, built: BuiltScene) -> Any:
    """A primitive whose mesh is shared with every other primitive of the same shape (one tessellation,
    one upload); its materials sit in object-linked material slots."""
    bpy = _runtime.bpy_module()
    key = _primitive_key(r)
    cached = built.shared_meshes.get(key)
    if cached is None:
        tmp = _Entry()
        obj = _build_mesh_like(r, f"bf_shared_{len(built.shared_meshes)}_{type(r).__name__}", tmp, mb, materials=False)
        me = obj.data
        bpy.data.objects.remove(obj)
        for _ in r.materials:
            me.materials.append(None)
        built.shared.data.append(("meshes", me))
        built.shared_meshes[key] = cached = (me, tmp.offset)
        entry.timings.update(tmp.timings)
    me, entry.offset = cached
    obj = bpy.data.objects.new(name, me)
    for i, mat in enumerate(_materials_for(r, name, entry, mb, built)):
        slot = obj.material_slots[i]
        slot.link = "OBJECT"
        slot.material = mat
    return obj


def _build_pointcloud(r: PointCloud, name: str, entry: _Entry, mb: MaterialBuilder) -> Any:
    """Native Cycles points: a vertex-only mesh + Geometry Nodes (Mesh to Points, radius from an
    attribute, Set Material)."""
    bpy = _runtime.bpy_module()
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
    c = r.colors_list[0]
    if isinstance(c, VertexColors) and n:
        ca = me.attributes.new(_COLOR_ATTR.format(0), "FLOAT_COLOR", "POINT")
        ca.data.foreach_set("color", np.ascontiguousarray(c.linear_rgba, dtype=np.float32).ravel())
    me.update()
    mat = mb.build(
        f"{name}_m0", r.materials[0], c, slot=0, entry=entry, emission_from_color=r.particle_emission_strength
    )
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


def _build_curve(r: CurveBezier, name: str, entry: _Entry, mb: MaterialBuilder, built: BuiltScene | None = None) -> Any:
    """A tube through the keypoints: a POLY spline bevelled to ``radius`` with filled caps."""
    bpy = _runtime.bpy_module()
    k32 = _recentre(r.keypoints, entry)
    cu = entry.add("curves", bpy.data.curves.new(name, "CURVE"))
    cu.dimensions = "3D"
    cu.bevel_mode = "ROUND"
    cu.bevel_depth = float(r.radius)
    cu.bevel_resolution = 6
    cu.use_fill_caps = True
    cu.twist_mode = "MINIMUM"
    sp = cu.splines.new("POLY")
    sp.points.add(len(k32) - 1)
    co = np.ones((len(k32), 4), dtype=np.float32)
    co[:, :3] = k32
    sp.points.foreach_set("co", co.ravel())
    sp.use_smooth = True
    for mat in _materials_for(r, name, entry, mb, built):
        cu.materials.append(mat)
    return bpy.data.objects.new(name, cu)


# ---------------------------------------------------------------------------------------------------
# lights and world
# ---------------------------------------------------------------------------------------------------


def _lights_key(scene: Any) -> tuple[Any, ...]:
    lights = scene.lights
    items = tuple((light.uid, light.revision("transform"), light.revision("appearance")) for light in lights)
    bg = lights.background
    env = lights.environment
    bg_key = None if bg is None else (bg.strength, tuple(bg.color), bg.color_space)
    env_key = None if env is None else (id(env), env.strength, tuple(env.quaternion), env.color_space)
    return (lights.revision, items, bg_key, env_key)


def _build_lights(scene: Any, sc: Any) -> _Entry:
    bpy = _runtime.bpy_module()
    entry = _Entry()
    for i, light in enumerate(scene.lights):
        name = f"bf_light_{i}_{light.tag}"[:60]
        if isinstance(light, PointLight):
            data = bpy.data.lights.new(name, "POINT")
            data.shadow_soft_size = light.shadow_soft_size
            data.use_soft_falloff = False
        elif isinstance(light, SpotLight):
            data = bpy.data.lights.new(name, "SPOT")
            data.shadow_soft_size = light.shadow_soft_size
            data.use_soft_falloff = False
            data.spot_size = light.spot_size
            data.spot_blend = light.spot_blend
        elif isinstance(light, SunLight):
            data = bpy.data.lights.new(name, "SUN")
            data.angle = light.angular_diameter
        elif isinstance(light, AreaLight):
            data = bpy.data.lights.new(name, "AREA")
            data.shape = {"square": "SQUARE", "circle": "DISK", "rectangle": "RECTANGLE", "ellipse": "ELLIPSE"}[
                light.shape
            ]
            data.size = light.size[0]
            data.size_y = light.size[1]
            data.normalize = True
        else:  # pragma: no cover - the IR has no other light types
            raise InvalidSceneError(f"light {light.tag!r}: unknown light type {type(light).__name__}")
        entry.add("lights", data)
        data.energy = float(light.strength)
        data.color = tuple(float(x) for x in light.linear_color)
        data.use_shadow = bool(light.use_shadow)
        data.exposure = 0.0
        data.use_temperature = False
        obj = bpy.data.objects.new(name, data)
        obj.visible_camera = False
        sc.collection.objects.link(obj)
        _set_matrix(obj, light.matrix_world)
        entry.objects.append(obj)
    return entry


def _build_world(scene: Any, sc: Any, mb: MaterialBuilder) -> _Entry:
    """The world: background light (colour x strength) plus the environment map; nothing else (the new
    World's 0.05 grey is replaced)."""
    import mathutils

    bpy = _runtime.bpy_module()
    entry = _Entry()
    world = entry.add("worlds", bpy.data.worlds.new("bf_world"))
    sc.world = world
    nt = world.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputWorld")
    out.target = "ALL"
    shaders = []
    bg = scene.lights.background
    if bg is not None and bg.strength > 0:
        node = nt.nodes.new("ShaderNodeBackground")
        node.inputs["Color"].default_value = (*(float(x) for x in bg.linear_color), 1.0)
        node.inputs["Strength"].default_value = float(bg.strength)
        shaders.append(node.outputs[0])
    env = scene.lights.environment
    if env is not None and env.strength > 0:
        img = mb.image_from_array("bf_environment", _rgba(env.linear_rgb_image()), "Linear Rec.709", entry)
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
        shaders.append(node.outputs[0])
        # importance map at the image's resolution (AUTOMATIC bakes 1024 wide: ~1.8 s per render here)
        world.cycles.sampling_method = "MANUAL"
        world.cycles.sample_map_resolution = int(min(max(img.size[0], 32), 1024))
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


def _rgba(rgb: np.ndarray) -> np.ndarray:
    out = np.ones(rgb.shape[:2] + (4,), dtype=np.float32)
    out[..., :3] = rgb
    return out


# ---------------------------------------------------------------------------------------------------
# attached .blend files
# ---------------------------------------------------------------------------------------------------

#: object types ``attach_blend`` parses into the IR (rendered from the IR) -- every other renderable
#: type (volumes, hair curves, grease pencil, ...) is linked from the attached file itself
_PARSED_TYPES = ("MESH", "CURVE", "SURFACE", "META", "FONT", "LIGHT", "CAMERA", "EMPTY", "POINTCLOUD")


def _build_attached(scene: Any, sc: Any) -> _Entry:
    """Append the scenes of ``scene.attached_blends`` (through blendfile.append_blend_scenes: auto-run
    off, Python drivers and text blocks removed) and link the objects the IR could not represent into
    the render scene; everything appended is owned by the returned entry."""
    entry = _Entry(key=tuple(scene.attached_blends))
    if not scene.attached_blends:
        return entry
    from . import blendfile

    bpy = _runtime.bpy_module()
    before = {idb.as_pointer() for idb in _all_ids(bpy)}
    try:
        for path in scene.attached_blends:
            scenes, _notes = blendfile.append_blend_scenes(path)
            for bs in scenes:
                for obj in bs.objects:
                    if obj.type not in _PARSED_TYPES and obj.name not in sc.collection.objects:
                        sc.collection.objects.link(obj)
                        obj.pass_index = 0
    finally:
        entry.ids = [idb for idb in _all_ids(bpy) if idb.as_pointer() not in before and idb != sc]
    return entry


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


# ---------------------------------------------------------------------------------------------------
# engine settings
# ---------------------------------------------------------------------------------------------------


def apply_engine_settings(
    sc: Any, settings: RenderSettings, scene: Any, device: str = "CPU", compute_device_type: str = ""
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
    if settings.pixel_filter == "box":
        cy.pixel_filter_type, cy.filter_width = "BOX", 1.0
    else:
        cy.pixel_filter_type, cy.filter_width = "GAUSSIAN", 1.5
    cy.sample_clamp_direct = float(settings.clamp_direct)
    cy.sample_clamp_indirect = float(settings.clamp_indirect)
    cy.blur_glossy = 0.0
    cy.use_light_tree = True
    mb = int(settings.max_bounces)
    # attached .blend content is not in the IR: the effect analysis cannot see it (volumes, hair, ...)
    attached = bool(getattr(scene, "attached_blends", None))
    eff = analyse_effects(scene) if settings.effects and not attached else None
    bounces = {
        "max_bounces": mb,
        "diffuse_bounces": mb,
        "glossy_bounces": mb,
        "transmission_bounces": mb,
        "volume_bounces": mb if attached else 0,
        "transparent_max_bounces": max(mb, 8),
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
        "blur_glossy": 0.0,
        **bounces,
        "threads": r.threads if settings.threads else "auto",
        "film_transparent": r.film_transparent,
        "view_transform": "Standard",
        "effects_used": eff is not None,
        "geometry_only": geometry_only,
    }


# ---------------------------------------------------------------------------------------------------
# whole-scene build and the cached translator
# ---------------------------------------------------------------------------------------------------


def _check_scene(scene: Any) -> None:
    from blendify_core.ir.scene import Scene

    if not isinstance(scene, Scene):
        raise InvalidSceneError(f"scene: expected a blendify_core.Scene, got {type(scene).__name__}")
    if scene.camera is None:
        raise InvalidSceneError("scene.camera: the scene has no camera; call scene.set_perspective_camera(...) first")


class Translator:
    """Keeps one translated scene in the bpy session and updates it incrementally.

    A different IR scene (another renderables collection) resets bpy to factory settings and removes
    everything; the same scene only gets what changed: new/removed/modified renderables, moved
    objects (matrix only), lights/world when any light changed, camera and engine settings always."""

    def __init__(self, device: str = "CPU", gpu_setup: Any = None) -> None:
        self.built: BuiltScene | None = None
        self._scene_ref: Any = None
        self._lights_key: Any = None
        self._transforms: dict[int, int] = {}
        self.device = device
        #: called after every factory reset when device == "GPU" (the reset forgets the preferences);
        #: returns the compute device type enabled, or "" to fall back to the CPU
        self.gpu_setup = gpu_setup
        self.compute_device_type = ""
        self.last_stats: dict[str, Any] = {}

    def _same_scene(self, scene: Any) -> bool:
        if self.built is None or self._scene_ref is None or self.built.generation != _runtime.generation():
            return False
        if self._scene_ref() is not scene.renderables:
            return False
        if not self._alive():
            # someone else reset or replaced the bpy session: the cached datablocks are gone
            self.built, self._scene_ref, self._lights_key = None, None, None
            self._transforms.clear()
            return False
        return True

    def _alive(self) -> bool:
        """Whether the cached datablocks still exist (cheap spot check)."""
        built = self.built
        if built is None:
            return False
        try:
            if _runtime.bpy_module().context.scene != built.bscene:
                return False
            for entry in [built.camera, *list(built.entries.values())[:1]]:
                for obj in entry.objects:
                    _ = obj.name
        except ReferenceError:
            return False
        return True

    def clear(self) -> None:
        """Remove every datablock of the cached scene (the bpy session is left empty, not reset)."""
        if self.built is not None and self.built.generation == _runtime.generation() and self._alive():
            self.built.remove()
            bpy = _runtime.bpy_module()
            for img in list(bpy.data.images):  # created by our renders ("Render Result", "Viewer Node")
                if img.type in ("RENDER_RESULT", "COMPOSITING"):
                    bpy.data.images.remove(img)
            try:
                _runtime.bpy_module().data.orphans_purge(do_recursive=True)
            except Exception:  # pragma: no cover - best effort
                pass
        self.built = None
        self._scene_ref = None
        self._lights_key = None
        self._transforms.clear()

    def sync(self, scene: Any, settings: RenderSettings) -> BuiltScene:
        """Bring the bpy scene in line with ``scene`` and ``settings``; returns the BuiltScene."""
        _check_scene(scene)
        bpy = _runtime.bpy_module()
        stats = {"new_scene": False, "built": 0, "moved": 0, "removed": 0, "lights_rebuilt": False}
        if not self._same_scene(scene):
            self.clear()
            _runtime.factory_reset()
            if self.device == "GPU" and self.gpu_setup is not None:
                self.compute_device_type = self.gpu_setup()
            self.built = BuiltScene(bscene=bpy.context.scene, generation=_runtime.generation())
            self._scene_ref = weakref.ref(scene.renderables)
            stats["new_scene"] = True
        built = self.built
        if built is None:  # set just above for a new scene; an internal invariant
            raise RenderError("cycles: the translated scene is missing (internal error)")
        try:
            self._sync_contents(scene, settings, built, stats)
        except BaseException:
            # a half-updated scene (error or Ctrl-C) is never reused
            self.clear()
            raise
        self.last_stats = stats
        return built

    def _sync_contents(self, scene: Any, settings: RenderSettings, built: BuiltScene, stats: dict[str, Any]) -> None:
        sc = built.bscene
        mb = MaterialBuilder()
        present = set()
        for i, r in enumerate(scene.renderables):
            present.add(r.uid)
            entry = built.entries.get(r.uid)
            key = _renderable_key(r)
            if entry is not None and entry.key != key:
                entry.remove()
                entry = None
            if entry is None:
                entry = _build_renderable(r, i, sc, mb, built)
                built.entries[r.uid] = entry
                self._transforms[r.uid] = r.revision("transform")
                stats["built"] += 1
            else:
                obj = entry.objects[0]
                if obj.pass_index != i + 1:  # an RNA write tags the depsgraph: only when it changed
                    obj.pass_index = i + 1
                if self._transforms.get(r.uid) != r.revision("transform"):
                    _set_matrix(obj, _object_matrix(r, entry))
                    self._transforms[r.uid] = r.revision("transform")
                    stats["moved"] += 1
        for uid in [u for u in built.entries if u not in present]:
            built.entries.pop(uid).remove()
            self._transforms.pop(uid, None)
            stats["removed"] += 1
        attached = tuple(getattr(scene, "attached_blends", ()))
        if attached != built.attached.key:
            built.attached.remove()
            built.attached = _build_attached(scene, sc)
            stats["attached_blends"] = len(attached)
        key = _lights_key(scene)
        if key != self._lights_key:
            built.lights.remove()
            built.world.remove()
            built.lights = _build_lights(scene, sc)
            built.world = _build_world(scene, sc, mb)
            self._lights_key = key
            stats["lights_rebuilt"] = True
        _apply_camera(built, scene.camera)
        device = "GPU" if (self.device == "GPU" and self.compute_device_type) else "CPU"
        built.engine_settings = apply_engine_settings(sc, settings, scene, device, self.compute_device_type)
        built.instance_tags = [r.tag for r in scene.renderables]


def build_scene(scene: Any, settings: RenderSettings | None = None, reset: bool = True) -> BuiltScene:
    """Build the bpy scene for ``scene`` from scratch in the current bpy session (see the module doc).

    ``settings`` defaults to the "final" preset. With ``reset=True`` (default) bpy is first reset to an
    empty factory scene; with ``reset=False`` the objects are added to the current scene."""
    from blendify_core.pipeline.settings import resolve_settings

    _check_scene(scene)
    settings = settings or resolve_settings("final")
    bpy = _runtime.bpy_module()
    with _runtime.BPY_LOCK:
        if reset:
            _runtime.factory_reset()
        built = BuiltScene(bscene=bpy.context.scene, generation=_runtime.generation())
        with _runtime.capture_output("build scene") as cap, _runtime.engine_errors("building the scene", cap):
            Translator()._sync_contents(scene, settings, built, {"built": 0, "moved": 0, "removed": 0})
        return built
