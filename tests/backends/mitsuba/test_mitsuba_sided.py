"""Cycles' sidedness rule on the IR's curve tubes (blendify_mitsuba/sided.py): Cycles' valid-reflection
normal, which BSDFs get wrapped, and that the wrapper changes nothing where both rules agree."""

from __future__ import annotations

import numpy as np
import pytest
from blendify_mitsuba import MitsubaBackend
from blendify_mitsuba.sided import SIDED_BSDF, valid_reflection_normal
from blendify_mitsuba.translate import MitsubaTranslator

import blendify_core as bf
from blendify_core import testing
from blendify_core.pipeline.settings import resolve_settings

_status = MitsubaBackend.probe()
if not _status.available:  # pragma: no cover - depends on the machine
    print(f"\nskipping the mitsuba backend tests: {_status.reason}")
    pytest.skip(f"mitsuba backend unavailable: {_status.reason}", allow_module_level=True)

pytestmark = pytest.mark.mitsuba

SETTINGS = resolve_settings(samples=4, max_bounces=2)


def _unit(v):
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


def test_valid_reflection_normal_lifts_the_mirror_direction_just_enough(mi_scalar):
    mi = mi_scalar
    rng = np.random.default_rng(3)
    bent = 0
    for _ in range(300):
        ng = _unit(rng.normal(size=3))
        wi = _unit(rng.normal(size=3))
        if wi @ ng < 0:
            wi = -wi
        n = _unit(ng + rng.uniform(0.0, 1.5) * _unit(rng.normal(size=3)))
        if n @ ng <= 0.05:
            continue
        out = np.array(valid_reflection_normal(mi.Vector3f(*ng), mi.Vector3f(*wi), mi.Vector3f(*n)), dtype=np.float64)
        t = min(0.9 * (wi @ ng), 0.01)
        r = 2 * (n @ wi) * n - wi
        assert abs(np.linalg.norm(out) - 1) < 1e-5
        if ng @ r >= t:
            assert np.allclose(out, n, atol=1e-6)  # already valid: unchanged
            continue
        bent += 1
        r2 = 2 * (out @ wi) * out - wi
        assert ng @ r2 == pytest.approx(t, abs=2e-4)  # the mirror direction leaves at the threshold
        assert out @ wi > 0  # the viewer is in front of the new normal
        assert abs(np.cross(n, ng) @ out) < 1e-4  # turned in the plane of n and ng
    assert bent > 20


def _curve_scene(material) -> bf.Scene:
    s = bf.Scene()
    keys = np.array([[-0.5, 0.0, 0.0], [0.5, 0.0, 0.0], [0.8, 0.4, 0.0]])
    s.renderables.add_curve_nurbs(keys, 0.1, material, bf.UniformColors((0.8, 0.3, 0.2)), tag="tube")
    s.renderables.add_cylinder_mesh(
        0.2, 0.3, bf.DiffuseMaterial(), bf.UniformColors((0.5, 0.5, 0.5)), translation=(0, -0.6, 0)
    )
    testing.look_at_camera(s, (32, 24), (0.0, -2.0, 1.0), (0, 0, 0))
    s.lights.add_sun(3.0)
    return s


@pytest.mark.parametrize(
    ("material", "wrapped"),
    [
        (bf.PrincipledBSDFMaterial(), True),
        (bf.DiffuseMaterial(), True),
        (bf.PrincipledBSDFMaterial(transmission_weight=1.0), False),  # its refraction must cross the surface
        (bf.PrincipledBSDFMaterial(alpha=0.5), False),  # the mask's pass-through too
    ],
)
def test_reflecting_curve_bsdfs_are_wrapped_meshes_are_not(mi_scalar, material, wrapped):
    tr = MitsubaTranslator(SETTINGS).translate(_curve_scene(material))
    tube = str(tr.scene_dict["r00000_m000"].bsdf())
    cylinder = str(tr.scene_dict["r00001_m000"].bsdf())
    assert ("GeometricSides" in tube) is wrapped
    assert "GeometricSides" not in cylinder
    assert SIDED_BSDF == "blendify_sided"


def test_wrapper_changes_nothing_where_both_rules_agree(mi_scalar):
    """A tube seen from the side under a sun: the wrapped and the plain BSDF give the same picture within
    noise (they differ only where the view grazes the tube between its faces and its normals)."""
    import blendify_mitsuba.translate as translate

    scene = _curve_scene(bf.DiffuseMaterial())
    wrapped = bf.render(scene, "mitsuba", samples=256, variant="scalar_rgb").rgba[..., :3]
    real = translate.material_lobes

    class _NoWrap:
        transmission = True

    try:
        translate.material_lobes = lambda m: _NoWrap()
        scene.renderables.add_sphere_nurbs(
            0.01, bf.DiffuseMaterial(), bf.UniformColors((1, 1, 1)), translation=(0, 0, -50)
        )
        plain = bf.render(scene, "mitsuba", samples=256, variant="scalar_rgb").rgba[..., :3]
    finally:
        translate.material_lobes = real
    assert wrapped.sum() > 0
    assert abs(wrapped.sum() / plain.sum() - 1) < 0.01


def test_grazing_view_evaluates_like_cycles_diffuse(mi_scalar):
    """Viewer in front of the face but behind the interpolated normal (the zone where the rules differ): the
    wrapper evaluates a Lambertian BSDF as Cycles does (albedo / pi x cos(normal, light), whatever side of
    the interpolated normal the viewer is on) and drops a sampled direction below the face. Both for one of
    Mitsuba's plugins and for a BSDF written in Python that states its diffuse odds (sampled as the mixture of
    its masked halves, as the layered Principled is)."""
    mi = mi_scalar
    import drjit as dr

    class Lambert(mi.BSDF):  # honours the context's lobe mask and states its odds, as the layered Principled
        diffuse_odds = 1.0

        def __init__(self, props):
            super().__init__(props)
            self.m_flags = mi.BSDFFlags.DiffuseReflection | mi.BSDFFlags.FrontSide
            self.m_components = [self.m_flags]

        def eval(self, ctx, si, wo, active=True):
            ok = (si.wi.z > 0) & (wo.z > 0) & ctx.is_enabled(mi.BSDFFlags.DiffuseReflection, 0)
            return mi.Color3f(0.5 * dr.inv_pi * wo.z) if ok else mi.Color3f(0.0)

        def pdf(self, ctx, si, wo, active=True):
            ok = (si.wi.z > 0) & (wo.z > 0) & ctx.is_enabled(mi.BSDFFlags.DiffuseReflection, 0)
            return dr.inv_pi * wo.z if ok else 0.0

        def eval_pdf(self, ctx, si, wo, active=True):
            return self.eval(ctx, si, wo, active), self.pdf(ctx, si, wo, active)

        def sample(self, ctx, si, s1, s2, active=True):
            bs = dr.zeros(mi.BSDFSample3f)
            if not ctx.is_enabled(mi.BSDFFlags.DiffuseReflection, 0):
                return bs, mi.Color3f(0.0)
            bs.wo = mi.warp.square_to_cosine_hemisphere(s2)
            bs.pdf = dr.inv_pi * bs.wo.z
            bs.sampled_type = int(mi.BSDFFlags.DiffuseReflection)
            return bs, mi.Color3f(0.5)

        def to_string(self):
            return "Lambert"

    mi.register_bsdf("test_lambert_py", lambda p: Lambert(p))
    from blendify_mitsuba.sided import register

    register()
    inners = {
        "mitsuba": mi.load_dict({"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.5, 0.5, 0.5]}}),
        "python": mi.load_dict({"type": "test_lambert_py"}),
    }
    n = _unit([0.0, np.sin(np.radians(20)), np.cos(np.radians(20))])  # interpolated normal, tilted 20 deg
    wi = _unit([0.0, -0.95, 0.2])  # in front of the face (z > 0), behind n
    assert wi @ n < 0 < wi[2]
    for name, inner in inners.items():
        wrapped = mi.load_dict({"type": SIDED_BSDF, "bsdf": inner})
        si = mi.SurfaceInteraction3f()
        si.n = mi.Normal3f(0, 0, 1)
        si.sh_frame = mi.Frame3f(mi.Vector3f(*n))
        si.wi = si.sh_frame.to_local(mi.Vector3f(*wi))
        for wo in ([0.0, 0.3, 0.95], [0.5, -0.2, 0.8], [0.0, -0.9, 0.1]):
            wo = _unit(wo)
            value = float(wrapped.eval(mi.BSDFContext(), si, si.sh_frame.to_local(mi.Vector3f(*wo)))[0])
            assert value == pytest.approx(0.5 / np.pi * max(n @ wo, 0.0), rel=1e-4, abs=1e-7), name
        below = 0
        rng = np.random.default_rng(5)
        for u, v in rng.uniform(size=(3000, 2)):  # ~1 % of the tilted cosine lobe lies below the face
            bs, weight = wrapped.sample(mi.BSDFContext(), si, 0.5, mi.Point2f(u, v))
            w = np.array(si.sh_frame.to_world(bs.wo), dtype=np.float64)
            if w[2] <= 0:
                below += 1
                assert float(bs.pdf) == 0.0 and float(weight[0]) == 0.0, name
        assert below > 0, name  # the tilted normal's hemisphere reaches below the face: those are dropped


def test_layered_principled_is_split_by_lobe_as_a_mixture(mi_scalar):
    """The layered Principled (honours the lobe mask, renormalising its odds) in the grazing zone: the wrapper
    evaluates its diffuse and glossy halves in their frames; a sampled direction's pdf is the halves' mixture
    by the diffuse odds (the pdf eval_pdf gives) and its weight eval / pdf; the pdf integrates to at most 1."""
    mi = mi_scalar
    from blendify_mitsuba import layered
    from blendify_mitsuba import principled as P
    from blendify_mitsuba.sided import register

    from blendify_core.ir.materials import PrincipledBSDFMaterial

    layered.register()
    register()
    material = PrincipledBSDFMaterial(roughness=0.4, coat_weight=0.5, coat_roughness=0.2)
    inner = mi.load_dict(P.layered_bsdf(P.principled_lobes(material, np.array([0.8, 0.4, 0.2]))))
    assert 0 < inner.diffuse_odds < 1
    wrapped = mi.load_dict({"type": SIDED_BSDF, "bsdf": inner})
    n = _unit([0.0, np.sin(np.radians(20)), np.cos(np.radians(20))])
    si = mi.SurfaceInteraction3f()
    si.n = mi.Normal3f(0, 0, 1)
    si.sh_frame = mi.Frame3f(mi.Vector3f(*n))
    si.wi = si.sh_frame.to_local(mi.Vector3f(*_unit([0.0, -0.95, 0.2])))
    ctx = mi.BSDFContext()
    rng = np.random.default_rng(7)
    kinds = set()
    for u in rng.uniform(size=(200, 3)):
        bs, weight = wrapped.sample(ctx, si, float(u[0]), mi.Point2f(float(u[1]), float(u[2])))
        if float(bs.pdf) <= 0:
            continue
        kinds.add(int(bs.sampled_type))
        value, pdf = wrapped.eval_pdf(ctx, si, bs.wo)
        assert float(pdf) == pytest.approx(float(bs.pdf), rel=1e-4)
        assert float(wrapped.pdf(ctx, si, bs.wo)) == pytest.approx(float(pdf), rel=1e-4)
        np.testing.assert_allclose(np.array(weight), np.array(value) / float(pdf), rtol=1e-4, atol=1e-7)
    assert kinds == {int(mi.BSDFFlags.DiffuseReflection), int(mi.BSDFFlags.GlossyReflection)}
    total = 0.0  # the pdf over the sphere (uniform directions): a density, at most 1 (samples below are lost)
    m = 4000
    for d in rng.normal(size=(m, 3)):
        total += float(wrapped.pdf(ctx, si, si.sh_frame.to_local(mi.Vector3f(*_unit(d)))))
    total *= 4 * np.pi / m
    assert 0.8 < total < 1.05
