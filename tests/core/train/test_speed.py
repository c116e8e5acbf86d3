"""Speed switches (``speed:``): validation, float32 geometry under autocast, unchanged checkpoints,
exact resumption with the switches on. Their speed is measured in benchmarks/bench_train.py, not here."""
import pytest
import torch

from cerberus_core.devices import native_bf16
from cerberus_core.errors import NonFiniteError
from cerberus_core.model import Cerberus
from cerberus_core.model.cerberus import ModelConfig
from cerberus_core.render.templates import icosphere
from cerberus_core.train import load_checkpoint, load_config, train
from cerberus_core.train.checkpoint import checkpoint_dir
from cerberus_core.train.objective import smoothness_term
from cerberus_core.train.speed import SpeedConfig, apply_speed, release_speed, resolve_autocast

FAST = ["speed.autocast=bf16", "speed.channels_last=true"]


def tiny_model(speed: SpeedConfig) -> Cerberus:
    torch.manual_seed(0)
    return apply_speed(Cerberus(ModelConfig(num_parts=4, sphere_level=1, width=8, shape_latent_dim=16,
                                            depth_offset=2.5)), speed)


def test_speed_switches_are_off_by_default_on_in_the_cpu_recipe_and_validated():
    for preset in ("paper", "paper_faithful", "tiny"):
        assert load_config(preset=preset).speed == SpeedConfig()
    assert load_config(preset="cpu").speed == SpeedConfig(autocast="auto", channels_last=True, smoothness_once=True)
    c = load_config(preset="tiny", overrides=FAST + ["speed.compile=true"])
    assert (c.speed.autocast, c.speed.channels_last, c.speed.compile) == ("bf16", True, True)
    with pytest.raises(ValueError, match="speed.autocast: expected one of .auto., .bf16. or null"):
        load_config(overrides=["speed.autocast=fp8"])
    with pytest.raises(ValueError, match="speed.channels_last: expected true/false"):
        load_config(overrides=["speed.channels_last=1"])
    with pytest.raises(ValueError, match=r"unknown config key.*speed.amp"):
        load_config(overrides=["speed.amp=bf16"])


def test_autocast_runs_the_trunk_in_bf16_and_keeps_heads_and_geometry_float32():
    plain, fast = tiny_model(SpeedConfig()), tiny_model(SpeedConfig(autocast="bf16", channels_last=True))
    assert plain.state_dict().keys() == fast.state_dict().keys()
    assert all(v.dtype == plain.state_dict()[k].dtype for k, v in fast.state_dict().items())
    images = torch.rand(4, 3, 32, 32)
    seen = []
    fast.encoder.register_forward_hook(lambda m, i, o: seen.append(o.c4.dtype))
    a, b = plain(images), fast(images)
    assert seen == [torch.bfloat16]
    for name, atol in (("local_vertices", 0.01), ("rotations", 0.05), ("shape_latent", 0.3)):
        assert getattr(b, name).dtype == torch.float32
        torch.testing.assert_close(getattr(b, name), getattr(a, name), atol=atol, rtol=0)  # bf16 rounding only
    assert b.maps.prob.dtype == torch.float32 and b.maps.prob.is_contiguous()
    torch.testing.assert_close(b.maps.uv, a.maps.uv, atol=0.5, rtol=0.05)
    release_speed(fast)
    torch.testing.assert_close(fast(images).local_vertices, a.local_vertices)  # float32 again


@pytest.mark.parametrize("switches", [
    pytest.param([], id="off"),
    pytest.param(FAST, id="autocast+channels_last"),
    pytest.param(["speed.smoothness_once=true"], id="smoothness_once"),
    pytest.param([*FAST, "speed.compile=true"], id="compile", marks=pytest.mark.slow),  # compiles for ~30 s
])
def test_resume_is_exact_with_the_speed_switches(tiny_config, tmp_path, switches):
    straight = train(tiny_config(*switches), tmp_path / "straight")
    with pytest.raises(NonFiniteError):
        train(tiny_config(*switches, "debug.poison_steps=[2]"), tmp_path / "killed")
    resumed = train(tiny_config(*switches), tmp_path / "killed", resume=True)
    assert resumed.step == 4
    a, b = straight.model.state_dict(), resumed.model.state_dict()
    assert a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)
    ck = load_checkpoint(checkpoint_dir(tmp_path / "killed") / "last.pt")
    assert all(v.dtype == torch.float32 for v in ck["model"].values() if v.is_floating_point())


def test_a_run_trained_with_switches_resumes_without_them(tiny_config, tmp_path):
    with pytest.raises(NonFiniteError):
        train(tiny_config(*FAST, "debug.poison_steps=[2]"), tmp_path / "run")
    resumed = train(tiny_config(), tmp_path / "run", resume=True)
    assert resumed.step == 4 and resumed.model.cnn_autocast is None



def test_smoothness_once_gives_the_same_loss_when_a_quadruplets_meshes_are_equal():
    sphere = icosphere(1)
    shapes = sphere.vertices * (0.5 + torch.rand(3, 1, 2, 1, 3))  # 3 quadruplets, 2 parts
    local = shapes.expand(3, 4, 2, -1, 3).reshape(12, 2, -1, 3)
    full = smoothness_term(local, sphere.dihedral, 3, once=False)
    once = smoothness_term(local, sphere.dihedral, 3, once=True)
    assert once.shape == full.shape == (12,) and torch.equal(once.mean(), full.mean())
    config = load_config(preset="tiny", overrides=["speed.smoothness_once=true"])
    assert config.speed.smoothness_once


@pytest.mark.parametrize(("flags", "expected"), [
    ({"avx2", "avx512f", "avx512_bf16"}, "bf16"),   # AVX-512 with native bf16 (e.g. Zen 4, Cooper Lake)
    ({"avx2", "amx_bf16", "amx_tile"}, "bf16"),     # Sapphire Rapids' AMX
    ({"fp", "asimd", "bf16"}, "bf16"),              # Arm v8.6
    ({"avx2", "fma", "avx512f"}, None),             # AVX-512 without bf16: emulated, slower than float32
    ({"avx2", "fma"}, None),                        # AVX2 only
    (set(), None),                                  # no /proc/cpuinfo (macOS, Windows)
])
def test_native_bf16_is_read_from_the_cpu_flags(flags, expected):
    native, why = native_bf16("cpu", frozenset(flags))
    assert native == (expected == "bf16") and why.startswith("this CPU has")


def test_autocast_auto_resolves_for_this_machine_and_other_values_pass_through():
    native, _ = native_bf16("cpu")
    value, why = resolve_autocast("auto", "cpu")
    assert value == ("bf16" if native else None) and why.startswith("auto: this CPU")
    assert resolve_autocast("bf16", "cpu") == ("bf16", "set in the config")
    assert resolve_autocast(None, "cpu") == (None, "set in the config")
    model = tiny_model(SpeedConfig(autocast="auto"))
    assert model.cnn_autocast == (torch.bfloat16 if native else None)


def test_a_run_saves_the_resolved_autocast_in_its_config(tiny_config, tmp_path):
    import yaml

    train(tiny_config("speed.autocast=auto"), tmp_path / "run")
    saved = yaml.safe_load((tmp_path / "run" / "config.yaml").read_text())
    assert saved["speed"]["autocast"] == resolve_autocast("auto", "cpu")[0]
