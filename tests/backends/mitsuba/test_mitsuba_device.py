"""device= for Mitsuba: "cpu", "gpu" or a variant family; GPUs are enumerated in one injectable place
(``blendify_mitsuba.variant.gpu_devices``) and probed through ``cached_probe``, both faked here. A request
for cuda_ad_rgb without a GPU never silently becomes another variant under strict=True."""

from __future__ import annotations

import pytest
from blendify_mitsuba import MitsubaBackend
from blendify_mitsuba import variant as V

import blendify_core as bf
from blendify_core import testing


@pytest.fixture
def fresh_choice(monkeypatch):
    """Variant choices made in this test only (the process-wide memo is replaced), automatic where the test
    names no variant (the suite's $BLENDIFY_MITSUBA_VARIANT is removed)."""
    monkeypatch.setattr(V, "_memo", {})
    monkeypatch.delenv(V.VARIANT_ENV, raising=False)
    return monkeypatch


@pytest.fixture
def fake_gpu(fresh_choice):
    fresh_choice.setattr(V, "gpu_devices", lambda: ["/dev/nvidia0"])
    real = V.cached_probe

    def probe(variant, libllvm):
        if variant.startswith("cuda"):
            return V.ProbeAttempt(variant, None, True, "CUDA probe passed (faked)")
        return real(variant, libllvm)

    fresh_choice.setattr(V, "cached_probe", probe)


@pytest.fixture
def no_gpu(fresh_choice):
    fresh_choice.setattr(V, "gpu_devices", lambda: [])


@pytest.mark.parametrize(
    ("kwargs", "used"),
    [({"device": "gpu"}, "GPU (cuda_ad_rgb)"), ({"device": "cuda"}, "GPU (cuda_ad_rgb)"), ({}, "GPU (cuda_ad_rgb)"),
     ({"variant": "cuda_ad_rgb"}, "GPU (cuda_ad_rgb)"), ({"device": "scalar"}, "CPU (scalar_rgb)")],
)  # fmt: skip
def test_variant_chosen_with_a_faked_gpu(fake_gpu, kwargs, used):
    choice = MitsubaBackend(**kwargs).device_choice()
    assert choice.used == used and choice.fallback is None
    assert "GPU /dev/nvidia0" in choice.found


def test_cpu_device_never_takes_the_gpu(fake_gpu):
    choice = MitsubaBackend(device="cpu").device_choice()
    assert choice.used.startswith("CPU (") and choice.fallback is None


@pytest.mark.parametrize("kwargs", [{"device": "gpu"}, {"variant": "cuda_ad_rgb"}, {"device": "cuda"}])
def test_cuda_without_gpu_strict_raises(no_gpu, kwargs):
    scene = testing.plane_scene("sun", resolution=(8, 8))
    with MitsubaBackend(**kwargs) as b:
        with pytest.raises(bf.BackendUnavailableError, match="no NVIDIA GPU.*strict=True refuses"):
            bf.render(scene, backend=b, samples=1, strict=True)


def test_cuda_without_gpu_warns_and_says_what_ran(no_gpu):
    with MitsubaBackend(device="gpu") as b:
        with pytest.warns(UserWarning, match="device='gpu' is unavailable here"):
            r = bf.render(testing.plane_scene("sun", resolution=(8, 8)), backend=b, samples=1)
    assert r.meta["device"] == f"CPU ({r.meta['variant']})" and not r.meta["variant"].startswith("cuda")


def test_device_and_variant_must_agree():
    with pytest.raises(bf.InvalidSceneError, match="disagree"):
        MitsubaBackend(device="gpu", variant="scalar_rgb")
    with pytest.raises(bf.InvalidSceneError, match="device: expected"):
        MitsubaBackend(device="tpu")
    assert MitsubaBackend(device="scalar", variant="scalar_rgb").session.requested_variant == "scalar_rgb"


def test_info_lists_the_devices(fake_gpu):
    lines = MitsubaBackend.info_details()
    assert "devices: CPU; GPU: /dev/nvidia0" in lines


def test_the_environment_names_the_variant_when_the_code_does_not(fake_gpu, monkeypatch):
    """$BLENDIFY_MITSUBA_VARIANT pins the variant of a backend created without variant= or device= (meta
    says so); an explicit variant or device wins; ``auto`` and empty mean the automatic choice."""
    monkeypatch.setenv(V.VARIANT_ENV, "scalar_rgb")
    b = MitsubaBackend()
    assert b.requested_variant == "scalar_rgb" and b.device_choice().used == "CPU (scalar_rgb)"
    r = bf.render(testing.plane_scene("sun", resolution=(8, 8)), backend=b, samples=1)
    assert r.meta["variant"] == "scalar_rgb" and "BLENDIFY_MITSUBA_VARIANT=scalar_rgb" in r.meta["variant_reason"]
    assert MitsubaBackend(device="gpu").device_choice().used == "GPU (cuda_ad_rgb)"
    assert MitsubaBackend(variant="cuda_ad_rgb").device_choice().used == "GPU (cuda_ad_rgb)"
    assert MitsubaBackend.info_details()[0] == "variant scalar_rgb (requested by BLENDIFY_MITSUBA_VARIANT=scalar_rgb)"
    for automatic in ("auto", "", " auto "):
        monkeypatch.setenv(V.VARIANT_ENV, automatic)
        assert MitsubaBackend().requested_variant is None
        assert MitsubaBackend().device_choice().used == "GPU (cuda_ad_rgb)"


@pytest.mark.parametrize("value", ["llvm", "scalar_spectral", "SCALAR_RGB", "1"])
def test_an_unknown_variant_in_the_environment_is_a_clear_error(monkeypatch, tmp_path, value):
    """Read when a backend is created (``bf.render(backend="mitsuba")`` creates its shared one once per process)
    and by the XML export, whose point clouds depend on the variant."""
    from blendify_mitsuba.export import export_mitsuba

    monkeypatch.setenv(V.VARIANT_ENV, value)
    with pytest.raises(bf.InvalidSceneError, match=r"BLENDIFY_MITSUBA_VARIANT: expected one of \['scalar_rgb'.*got"):
        MitsubaBackend()
    with pytest.raises(bf.InvalidSceneError, match="BLENDIFY_MITSUBA_VARIANT: expected"):
        export_mitsuba(testing.plane_scene("sun", resolution=(8, 8)), tmp_path / "scene.xml")
    assert MitsubaBackend(variant="scalar_rgb").requested_variant == "scalar_rgb"  # the code's choice needs no look
    assert any("BLENDIFY_MITSUBA_VARIANT: expected" in line for line in MitsubaBackend.info_details())
