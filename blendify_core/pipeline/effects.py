"""Which light transport a scene needs (``bf.analyse_effects``), so backends simulate nothing more."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from blendify_core.ir.lights import Light, SunLight
from blendify_core.ir.physics import material_lobes
from blendify_core.ir.renderables import CircleMesh, CubeMesh, EllipsoidNURBS, PlaneMesh, PointCloud, SphereNURBS
from blendify_core.ir.scene import Scene
from blendify_core.ir.validate import strict_api, strict_arguments

__all__ = ["Effects", "analyse_effects"]

_CONVEX = (SphereNURBS, EllipsoidNURBS, CubeMesh, PlaneMesh, CircleMesh)
#: the closed ones among them: a light inside one lights its inside, which then sees itself
_CLOSED = (SphereNURBS, EllipsoidNURBS, CubeMesh)
_FIELDS = (
    "shadows",
    "indirect_diffuse",
    "glossy",
    "transmission",
    "caustics",
    "transparency",
    "emission",
    "background",
)


@strict_api
@dataclass(frozen=True)
class Effects:
    """Light-transport effects a scene calls for; ``reasons`` says why each one is on or off."""

    shadows: bool = True
    indirect_diffuse: bool = True
    glossy: bool = True
    transmission: bool = True
    caustics: bool = True
    transparency: bool = True
    emission: bool = True
    background: bool = True
    reasons: dict[str, str] = field(default_factory=dict, compare=False)

    def to_dict(self) -> dict[str, bool | dict[str, str]]:
        """Each effect's flag plus ``reasons`` (effect -> why), as recorded in ``meta["effects"]``."""
        return {**{f: getattr(self, f) for f in _FIELDS}, "reasons": dict(self.reasons)}

    @classmethod
    def full(cls) -> Effects:
        return cls(reasons={f: "full simulation requested" for f in _FIELDS})


@strict_arguments
def analyse_effects(scene: Scene) -> Effects:
    """Analyse a scene: shadows, indirect diffuse, glossy, transmission, caustics, transparency, emission
    and background light, each with the reason."""
    r: dict[str, str] = {}
    renderables = list(scene.renderables)
    lights = [light for light in scene.lights if light.strength > 0]
    bg = scene.lights.background is not None and scene.lights.background.strength > 0
    env = scene.lights.environment is not None and scene.lights.environment.strength > 0

    emitters = [(f"material of {o.tag!r}") for o in renderables for m in o.materials if m.is_emissive]
    emitters += [
        f"point cloud {o.tag!r} emits"
        for o in renderables
        if isinstance(o, PointCloud) and o.particle_emission_strength > 0
    ]
    emission = bool(emitters)
    r["emission"] = emitters[0] if emission else "no emissive material"

    background = bg or env
    r["background"] = ("environment map" if env else "background light") if background else "no background light"

    casters = [o for o in renderables if o.emit_shadows]
    catchers = [o for o in renderables if isinstance(o, PlaneMesh) and o.shadow_catcher]
    shadow_lights = [light for light in lights if light.use_shadow]
    if catchers:
        shadows, r["shadows"] = True, f"shadow catcher {catchers[0].tag!r}"
    elif not casters:
        shadows, r["shadows"] = False, "no object casts shadows"
    elif shadow_lights:
        shadows, r["shadows"] = True, f"light {shadow_lights[0].tag!r} casts shadows"
    elif background or emission:
        shadows, r["shadows"] = True, "background or emissive light is occluded by objects"
    else:
        shadows, r["shadows"] = False, "no light casts shadows"

    # per object: which lobes its materials have
    glossy_objs, transmissive, transparent, diffuse_objs = [], [], [], []
    for o in renderables:
        for m in o.materials:
            lobes = material_lobes(m)
            if lobes.specular:
                glossy_objs.append(o.tag)
            if lobes.transmission:
                transmissive.append(o.tag)
            if lobes.alpha:
                transparent.append(o.tag)
            if lobes.diffuse:
                diffuse_objs.append(o.tag)
        for c in o.colors_list:
            if getattr(c, "has_alpha", False):
                transparent.append(o.tag)

    several = len(renderables) > 1
    concave = [o for o in renderables if not isinstance(o, _CONVEX)]
    specular_paths = sorted(set(glossy_objs) | set(transmissive))
    # a closed convex object with a light inside lights its own inside (a room made of one sphere or cube);
    # looked for only where it decides something (a lone object's indirect light, an object that could focus
    # light onto itself): the test tessellates the object, 1 ms per sphere (2 s for 2000)
    self_receivers = set(specular_paths) & set(diffuse_objs)
    lit_inside = [o for o in renderables if (not several or o.tag in self_receivers) and _holds_a_light(o, lights)]
    # light passing through a transparent or refractive convex object reaches its own inside
    see_through = [o for o in renderables if o.tag in transparent or o.tag in transmissive]
    if several:
        indirect, r["indirect_diffuse"] = True, f"{len(renderables)} objects can light each other"
    elif concave:
        indirect, r["indirect_diffuse"] = True, f"{concave[0].tag!r} may see itself (not convex)"
    elif lit_inside:
        indirect, r["indirect_diffuse"] = True, f"{lit_inside[0].tag!r} has a light inside: its inside sees itself"
    elif see_through:
        indirect, r["indirect_diffuse"] = True, f"{see_through[0].tag!r} is see-through: its inside sees itself"
    else:
        indirect, r["indirect_diffuse"] = False, "a single convex object (or none), opaque, cannot light itself"

    glossy = bool(glossy_objs)
    r["glossy"] = f"specular material on {glossy_objs[0]!r}" if glossy else "all materials are diffuse"
    transmission = bool(transmissive)
    r["transmission"] = f"transmissive material on {transmissive[0]!r}" if transmission else "no transmissive material"
    transparency = bool(transparent)
    r["transparency"] = f"alpha < 1 on {transparent[0]!r}" if transparency else "everything is opaque"
    # caustics = light -> glossy/refractive surface -> diffuse surface. Any roughness counts: Cycles' caustics
    # switches drop every glossy bounce after a diffuse one, and a rough reflector still lights the floor
    # (measured: a roughness-0.5 metal ball on a floor loses visible light without them)
    concave_tags = {o.tag for o in concave} | {o.tag for o in see_through} | {o.tag for o in lit_inside}
    pair = next(
        ((sp, rc) for sp in specular_paths for rc in dict.fromkeys(diffuse_objs) if rc != sp or sp in concave_tags),
        None,
    )
    has_light = bool(lights) or background or emission
    caustics = pair is not None and has_light
    r["caustics"] = (
        f"specular {pair[0]!r} can focus light onto {pair[1]!r}"
        if caustics and pair is not None
        else "no glossy or refractive surface between a light and a diffuse one (no sharp specular either)"
    )
    if not has_light and not catchers:  # a shadow catcher keeps its reason (and its compositing path)
        r["shadows"] = "no light at all"
        shadows = False
    return Effects(
        shadows=shadows,
        indirect_diffuse=indirect,
        glossy=glossy,
        transmission=transmission,
        caustics=caustics,
        transparency=transparency,
        emission=emission,
        background=background,
        reasons=r,
    )


def _holds_a_light(obj: object, lights: list[Light]) -> bool:
    """Whether a positioned light (point, spot, area: not the sun) lies inside the closed convex ``obj``:
    inside every face plane of its world-space tessellation (the side of the shape's centroid)."""
    if not isinstance(obj, _CLOSED):
        return False
    lo, hi = obj.world_bounds()  # cheap rejection before the tessellation
    positioned = [
        light
        for light in lights
        if not isinstance(light, SunLight) and np.all((light.translation > lo) & (light.translation < hi))
    ]
    if not positioned:
        return False
    mesh = obj.to_mesh()
    m = obj.matrix_world
    v = mesh.vertices @ m[:3, :3].T + m[:3, 3]
    tri = v[mesh.faces.reshape(-1, 3)]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    keep = np.linalg.norm(n, axis=1) > 0
    n, p0 = n[keep], tri[keep, 0]
    inner = np.sign(np.einsum("fi,fi->f", n, v.mean(axis=0) - p0))
    for light in positioned:
        side = np.einsum("fi,fi->f", n, np.asarray(light.translation, dtype=np.float64) - p0)
        if np.all(side * inner > 0):
            return True
    return False
