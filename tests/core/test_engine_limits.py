"""Biased render settings an engine cannot apply (``Backend.unapplied_settings``): listed in
``meta["approximations"]``, refused by ``strict=True``, and a crosscheck pair whose other side applies them is
reported as limited by the engine (neither passed nor failed)."""

from __future__ import annotations

import pytest
from core_fake_backend import FlatPlane

import blendify_core as bf
from blendify_core.errors import UnsupportedFeatureError
from blendify_core.pipeline.settings import ENGINE_LIMIT_PREFIX, engine_limits, resolve_settings, settings_bias
from blendify_core.registry import register_backend, unregister_backend
from blendify_core.testing import depth_plane_scene


class _Plane(FlatPlane):
    """The flat grey plane, dimmed by 10 % when the indirect light is clamped and this engine applies the
    clamp (as a path tracer's clamp darkens the picture)."""

    def gain(self, settings):
        return 0.9 if settings.clamp_indirect and "clamp_indirect" not in self.unapplied_settings else 1.0


class Applies(_Plane):
    name = "limits-applies"


class CannotApply(_Plane):
    name = "limits-cannot"
    unapplied_settings = ("clamp_direct", "clamp_indirect", "filter_glossy", "bounce_limits")


class CannotApplyEither(CannotApply):
    name = "limits-cannot-2"


@pytest.fixture
def fakes():
    for cls in (Applies, CannotApply, CannotApplyEither):
        register_backend(cls.name, cls)
    yield
    for cls in (Applies, CannotApply, CannotApplyEither):
        unregister_backend(cls.name)
    bf.close_backends()


def test_engine_limits_lines_follow_the_bias_lines():
    s = resolve_settings("final", clamp_indirect=10.0, filter_glossy=1.0, glossy_bounces=4, denoise=True)
    lines = engine_limits(s, CannotApply.unapplied_settings)
    assert len(lines) == 3 and all(x.startswith(ENGINE_LIMIT_PREFIX) for x in lines)
    assert [x[len(ENGINE_LIMIT_PREFIX) :] for x in lines] == [
        b for b in settings_bias(s) if b.startswith(("clamp_indirect=10", "filter_glossy=1", "bounce limits"))
    ]
    assert "glossy 4" in lines[2]
    assert engine_limits(resolve_settings("final"), CannotApply.unapplied_settings) == []
    assert engine_limits(s, ()) == []


def test_render_lists_unapplied_settings_and_strict_refuses(fakes):
    scene = depth_plane_scene()
    plain = bf.render(scene, CannotApply.name, samples=1)
    assert not any(a.startswith(ENGINE_LIMIT_PREFIX) for a in plain.meta["approximations"])
    res = bf.render(scene, CannotApply.name, samples=1, clamp_indirect=10.0, diffuse_bounces=2, max_bounces=6)
    limits = [a for a in res.meta["approximations"] if a.startswith(ENGINE_LIMIT_PREFIX)]
    assert len(limits) == 2
    assert any("clamp_indirect=10" in a for a in limits) and any("diffuse 2" in a for a in limits)
    # the engine that applies them lists nothing (its bias says what it applied)
    ok = bf.render(scene, Applies.name, samples=1, clamp_indirect=10.0)
    assert not any(a.startswith(ENGINE_LIMIT_PREFIX) for a in ok.meta["approximations"])
    assert any("clamp_indirect=10" in b for b in ok.meta["bias"])
    with pytest.raises(UnsupportedFeatureError, match=r"limits-cannot.*cannot apply.*clamp_indirect=10.*strict"):
        bf.render(scene, CannotApply.name, samples=1, clamp_indirect=10.0, strict=True)
    bf.render(scene, CannotApply.name, samples=1, strict=True)  # nothing biased: nothing refused


def test_crosscheck_reports_the_pair_limited_by_the_engine(fakes):
    scene = depth_plane_scene()
    names = (Applies.name, CannotApply.name, CannotApplyEither.name)
    rep = bf.crosscheck(scene, backends=names, samples=4, passes=1, outputs=("rgb",), clamp_indirect=10.0)
    limited = {(Applies.name, CannotApply.name), (Applies.name, CannotApplyEither.name)}
    assert set(rep.limited) == limited and set(rep.limited_reports) == limited
    for key in limited:
        assert len(rep.limited[key]) == 1 and rep.limited[key][0].startswith(ENGINE_LIMIT_PREFIX + "clamp_indirect=10")
        assert not rep.limited_reports[key].passed  # judged, it would fail: the clamp darkens one side by 10 %
    # two engines that both cannot apply the clamp render the same picture: judged as usual
    assert list(rep.pairs) == [(CannotApply.name, CannotApplyEither.name)] and rep.passed
    text = rep.summary()
    assert f"### {Applies.name} vs {CannotApply.name}: LIMITED BY THE ENGINE (not judged)" in text
    assert "LIMITED" in repr(rep)
    # without the biased setting every pair is judged
    plain = bf.crosscheck(scene, backends=names[:2], samples=4, passes=1, outputs=("rgb",))
    assert not plain.limited and list(plain.pairs) == [names[:2]] and plain.passed


class OwnSetting(_Plane):
    """An engine with a setting of its own (``exposure``) that doubles the picture and no other engine has."""

    name = "limits-own"

    def __init__(self, exposure: float = 1.0, **options):
        super().__init__(**options)
        self.exposure = exposure

    def gain(self, settings):
        return self.exposure

    def render(self, native, settings):
        res = super().render(native, settings)
        if self.exposure != 1.0:
            res.meta["engine_only_settings"] = [f"own.exposure={self.exposure:g} (default: 1)"]
        return res


def test_a_setting_only_one_engine_applies_limits_its_pairs(fakes):
    register_backend(OwnSetting.name, OwnSetting)
    try:
        scene = depth_plane_scene()
        names = (OwnSetting.name, CannotApply.name, CannotApplyEither.name)
        kw = {"samples": 4, "passes": 1, "outputs": ("rgb",)}
        rep = bf.crosscheck(scene, backends=names, backend_options={OwnSetting.name: {"exposure": 2.0}}, **kw)
        line = f"setting only one engine applies: {OwnSetting.name}: own.exposure=2 (default: 1)"
        assert rep.limited == {
            (OwnSetting.name, CannotApply.name): [line],
            (OwnSetting.name, CannotApplyEither.name): [line],
        }
        assert list(rep.pairs) == [(CannotApply.name, CannotApplyEither.name)]
        assert "LIMITED BY THE ENGINE (not judged)" in rep.summary()
        assert not bf.crosscheck(scene, backends=names[:2], **kw).limited  # exposure 1: judged
    finally:
        unregister_backend(OwnSetting.name)


def test_summary_heading_names_both_limits():
    from blendify_core.evaluate.report import _limited_heading
    from blendify_core.ir.attachments import IR_LIMIT_PREFIX

    ir = IR_LIMIT_PREFIX + "x.blend: a Checker node baked"
    eng = ENGINE_LIMIT_PREFIX + "clamp_indirect=10: ..."
    assert _limited_heading([ir]).startswith("LIMITED BY THE IR (")
    assert _limited_heading([eng]).startswith("LIMITED BY THE ENGINE (")
    assert _limited_heading([eng, ir]).startswith("LIMITED BY THE IR AND THE ENGINE (")
