"""device= for Cycles: "cpu", "gpu" or a compute type; the GPU list is injectable
(``blendify_blender.session.list_gpu_devices``), so the choice is tested with faked devices here, where
no GPU exists; without one, strict=True refuses and otherwise a visible warning, meta["device"] says what ran."""

from __future__ import annotations

import pytest
from blendify_blender import CyclesBackend
from blendify_blender import session as cycles_session

import blendify_core as bf
from blendify_core import testing

FAKE = [("CUDA", "Fake RTX 1"), ("OPTIX", "Fake RTX 1"), ("HIP", "Fake Radeon")]


@pytest.fixture
def fake_gpus(monkeypatch):
    monkeypatch.setattr(cycles_session, "list_gpu_devices", lambda: list(FAKE))
    return FAKE


@pytest.mark.parametrize(
    ("device", "used"),
    [
        ("gpu", "GPU (OPTIX: Fake RTX 1)"),  # OPTIX is preferred over CUDA
        ("cuda", "GPU (CUDA: Fake RTX 1)"),
        ("HIP", "GPU (HIP: Fake Radeon)"),
        ("cpu", "CPU"),
    ],
)
def test_device_choice_with_a_faked_gpu_list(fake_gpus, device, used):
    choice = CyclesBackend(device=device).device_choice()
    assert choice.used == used and choice.fallback is None


def test_an_absent_compute_type_falls_back_with_the_reason(fake_gpus):
    choice = CyclesBackend(device="ONEAPI").device_choice()
    assert choice.used == "CPU" and "no ONEAPI device" in choice.fallback and "GPU CUDA: Fake RTX 1" in choice.fallback


def test_gpu_choice_reaches_the_cycles_scene(fake_gpus, monkeypatch):
    """With a (faked) OPTIX device the session enables OPTIX after its factory reset and the translated
    scene renders with cy.device = 'GPU' (Cycles itself then finds no device here and uses the CPU)."""
    enabled = []
    monkeypatch.setattr(cycles_session, "enable_gpu", lambda kind: enabled.append(kind) or kind)
    monkeypatch.setattr("blendify_blender.enable_gpu", cycles_session.enable_gpu)
    with CyclesBackend(device="gpu") as b:
        r = bf.render(testing.plane_scene("sun", resolution=(8, 8)), backend=b, samples=1)
    assert enabled == ["OPTIX"]
    es = r.meta["engine_settings"]
    assert (es["device"], es["compute_device_type"]) == ("GPU", "OPTIX")
    assert r.meta["device"] == "GPU (OPTIX: Fake RTX 1)"


def test_no_gpu_strict_raises_otherwise_warns(monkeypatch):
    monkeypatch.setattr(cycles_session, "list_gpu_devices", lambda: [])
    scene = testing.plane_scene("sun", resolution=(8, 8))
    with CyclesBackend(device="gpu") as b:
        with pytest.raises(bf.BackendUnavailableError, match="no GPU compute device.*strict=True"):
            bf.render(scene, backend=b, samples=1, strict=True)
        with pytest.warns(UserWarning, match="device='gpu' is unavailable here"):
            r = bf.render(scene, backend=b, samples=1)
    assert r.meta["device"] == "CPU" and r.meta["engine_settings"]["device"] == "CPU"
    assert any("device='gpu'" in w for w in r.meta["warnings"])


def test_cpu_renders_without_enumerating(monkeypatch):
    monkeypatch.setattr(cycles_session, "list_gpu_devices", lambda: pytest.fail("enumerated for device='cpu'"))
    r = bf.render(testing.plane_scene("sun", resolution=(8, 8)), backend="cycles", samples=1, device="cpu")
    assert r.meta["device"] == "CPU"


def test_bad_device_names_the_choices():
    with pytest.raises(bf.InvalidSceneError, match=r"device: expected 'cpu', 'gpu' or one of \['OPTIX'"):
        CyclesBackend(device="TPU")


def test_info_lists_the_devices(fake_gpus, capsys):
    from blendify_core.cli.main import main

    assert main(["info"]) == 0
    out = capsys.readouterr().out
    assert "devices: CPU, GPU CUDA: Fake RTX 1, GPU OPTIX: Fake RTX 1, GPU HIP: Fake Radeon" in out


def test_blendify_look_reaches_cycles():
    """quality='blendify': Blender's render defaults as blendify 2.1 left them, stated as bias in meta."""
    scene = testing.plane_scene("sun", resolution=(8, 8))
    r = bf.render(scene, backend="cycles", quality="blendify", samples=2, effects=False)
    es = r.meta["engine_settings"]
    assert es["pixel_filter"] == ("BLACKMAN_HARRIS", 1.5)
    assert (es["clamp_indirect"], es["blur_glossy"], es["adaptive"]) == (10.0, 1.0, True)
    bounces = ("max_bounces", "diffuse_bounces", "glossy_bounces", "transmission_bounces", "transparent_max_bounces")
    assert [es[k] for k in bounces] == [12, 4, 4, 12, 8]
    assert any("clamp_indirect=10" in b for b in r.meta["bias"]) and any("filter_glossy" in b for b in r.meta["bias"])
    final = bf.render(testing.plane_scene("sun", resolution=(8, 8)), backend="cycles", quality="final", samples=2)
    assert final.meta["bias"] == [] and final.meta["engine_settings"]["blur_glossy"] == 0.0
    assert final.meta["engine_settings"]["pixel_filter"] == ("BOX", 1.0)


def test_info_says_when_there_is_no_gpu(monkeypatch):
    monkeypatch.setattr(cycles_session, "list_gpu_devices", lambda: [])
    assert CyclesBackend.info_details() == [
        "devices: CPU; GPU: none (Cycles looked for OPTIX, CUDA, HIP, METAL, ONEAPI)"
    ]


def test_isolated_backend_decides_the_device_in_its_worker():
    """isolate=True: bpy runs only in the worker, which chooses the device; strict=True is refused there,
    otherwise the parent warns and meta["device"] says what ran (this machine has no GPU)."""
    if cycles_session.list_gpu_devices():
        pytest.skip("this machine has a GPU: no fallback to check")
    scene = testing.plane_scene("sun", resolution=(8, 8))
    with CyclesBackend(device="gpu", isolate=True) as b:
        assert b.device_choice() is None
        with pytest.raises(bf.BackendUnavailableError, match="strict=True refuses"):
            bf.render(scene, backend=b, samples=1, strict=True)
        with pytest.warns(UserWarning, match="device='gpu' is unavailable here"):
            r = bf.render(scene, backend=b, samples=1)
    assert r.meta["device"] == "CPU" and "device_fallback" not in r.meta
