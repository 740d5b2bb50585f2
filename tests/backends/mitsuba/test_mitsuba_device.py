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
    """Variant choices made in this test only (the process-wide memo is replaced)."""
    monkeypatch.setattr(V, "_memo", {})
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
