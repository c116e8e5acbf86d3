"""The training loop: learning on a fixed batch, exact resumption, non-finite handling, outputs."""
import csv
from pathlib import Path

import pytest
import torch

from cerberus_core.datasets.dataset import Dataset
from cerberus_core.errors import NonFiniteError
from cerberus_core.run import Run
from cerberus_core.train import load_checkpoint, train
from cerberus_core.train.checkpoint import checkpoint_dir


def params(model):
    return {k: v.detach().clone() for k, v in model.state_dict().items()}


def assert_same_weights(a, b):
    assert a.keys() == b.keys()
    for k in a:
        assert torch.equal(a[k], b[k]), f"{k} differs"


def rows(run_dir):
    with open(run_dir / "metrics.csv", newline="") as f:
        return list(csv.DictReader(f))


class FirstItems(torch.utils.data.Dataset):
    """The first ``n`` quadruplets of a dataset, keeping its ``image_size`` and ``scene``."""

    def __init__(self, dataset, n):
        self.dataset, self.n = dataset, n
        self.image_size, self.scene = dataset.image_size, dataset.scene

    def __len__(self):
        return self.n

    def __getitem__(self, i):
        return self.dataset[i]


def test_a_few_steps_reduce_the_loss_on_a_fixed_batch(tiny_config, tiny_root, tmp_path):
    # batch_size 2 = the whole 2-quadruplet dataset: every step sees the same quadruplets.
    data = FirstItems(Dataset.open(tiny_root).quadruplets(), 2)
    cfg = tiny_config("train.steps=20", "train.batch_size=2", "train.image_every=0", "train.checkpoint_every=100",
                      "optim.lr=0.002")
    result = train(cfg, tmp_path / "run", dataset=data)
    totals = [float(r["total"]) for r in rows(tmp_path / "run")]
    assert len(totals) == 20
    first, last = sum(totals[:3]) / 3, sum(totals[-3:]) / 3
    assert last < 0.9 * first, totals
    assert result.step == 20 and result.skipped == 0


def test_resumed_run_ends_with_the_same_weights_as_an_uninterrupted_one(tiny_config, tmp_path):
    straight = train(tiny_config(), tmp_path / "straight")  # 4 steps, checkpoint at 2 and 4
    # The interrupted run dies at step 3 (a poisoned batch stops it) after its step-2 checkpoint.
    with pytest.raises(NonFiniteError):
        train(tiny_config("debug.poison_steps=[2]"), tmp_path / "killed")
    assert load_checkpoint(checkpoint_dir(tmp_path / "killed") / "last.pt")["step"] == 2
    resumed = train(tiny_config(), tmp_path / "killed", resume=True)
    assert resumed.step == 4
    assert_same_weights(params(straight.model), params(resumed.model))
    ck_a = load_checkpoint(checkpoint_dir(tmp_path / "straight") / "last.pt")
    ck_b = load_checkpoint(checkpoint_dir(tmp_path / "killed") / "last.pt")
    for group_a, group_b in zip(ck_a["optimizer"]["state"].values(), ck_b["optimizer"]["state"].values(), strict=True):
        assert torch.equal(group_a["exp_avg"], group_b["exp_avg"])
    assert [r["step"] for r in rows(tmp_path / "killed")] == ["1", "2", "3", "4"]  # no duplicates
    assert [r["total"] for r in rows(tmp_path / "killed")] == [r["total"] for r in rows(tmp_path / "straight")]


def test_resume_is_exact_with_partial_pose_mixing(tiny_config, tmp_path):
    """losses.pose_mixing < 1 draws from the objective's generator too: a resumed run draws what the straight one did."""
    straight = train(tiny_config("losses.pose_mixing=0.5"), tmp_path / "straight")
    with pytest.raises(NonFiniteError):
        train(tiny_config("losses.pose_mixing=0.5", "debug.poison_steps=[2]"), tmp_path / "killed")
    resumed = train(tiny_config("losses.pose_mixing=0.5"), tmp_path / "killed", resume=True)
    assert resumed.step == 4
    assert_same_weights(params(straight.model), params(resumed.model))
    assert [r["total"] for r in rows(tmp_path / "killed")] == [r["total"] for r in rows(tmp_path / "straight")]
    mixed_fully = train(tiny_config(), tmp_path / "eq3")  # and the draws differ from equation 3's
    assert [r["total"] for r in rows(tmp_path / "eq3")] != [r["total"] for r in rows(tmp_path / "straight")]
    assert mixed_fully.step == 4


def test_resume_refuses_a_different_run_and_fresh_start_refuses_an_existing_one(tiny_config, tmp_path):
    train(tiny_config("train.steps=2"), tmp_path / "run")
    with pytest.raises(FileExistsError, match="pass `resume=True` to continue it"):
        train(tiny_config("train.steps=2"), tmp_path / "run")
    with pytest.raises(ValueError, match="optim.lr"):
        train(tiny_config("optim.lr=0.1"), tmp_path / "run", resume=True)
    with pytest.raises(FileNotFoundError, match="no checkpoint"):
        train(tiny_config(), tmp_path / "other", resume=True)


def test_nonfinite_loss_stops_and_keeps_the_last_good_checkpoint(tiny_config, tmp_path):
    run = tmp_path / "run"
    with pytest.raises(NonFiniteError, match=r"step 3 .*last good checkpoint .*last.pt"):
        train(tiny_config("debug.poison_steps=[3]"), run)
    payload = load_checkpoint(checkpoint_dir(run) / "last.pt")
    assert payload["step"] == 2
    assert all(torch.isfinite(v).all() for v in payload["model"].values() if v.is_floating_point())
    assert not (run / "model.safetensors").exists()


def test_nonfinite_step_is_skipped_without_touching_weights_or_batchnorm(tiny_config, tmp_path):
    before = train(tiny_config("train.steps=1"), tmp_path / "ref").model
    result = train(tiny_config("train.steps=2", "train.on_nonfinite=skip", "debug.poison_steps=[1]"),
                   tmp_path / "run")
    assert result.skipped == 1
    assert_same_weights(params(before), params(result.model))  # the poisoned step changed nothing
    with pytest.raises(NonFiniteError, match="non-finite"):
        train(tiny_config("train.on_nonfinite=skip", "train.max_consecutive_skips=1",
                          "debug.poison_steps=[1, 2]"), tmp_path / "run2")


def test_run_folder_outputs_and_safe_loading(tiny_config, tmp_path):
    run = tmp_path / "run"
    result = train(tiny_config(), run)
    for name in ("config.yaml", "metrics.csv", "loss_curves.png", "model.safetensors", "checkpoints/last.pt",
                 "images/step_0000002.png", "images/step_0000004.png"):
        assert (run / name).is_file(), name
    payload = torch.load(run / "checkpoints" / "last.pt", weights_only=True)  # no arbitrary pickles
    assert payload["step"] == 4 and "rng" in payload and "optimizer" in payload
    for source in (run, run / "model.safetensors", run / "checkpoints" / "last.pt"):
        loaded = Run.load(source)
        model, config = loaded.model, loaded.config
        assert config.model.depth_offset == pytest.approx(result.model.config.depth_offset)
        assert_same_weights(params(model), params(result.model))
        assert not model.training


class InterruptAt(FirstItems):
    """Sends SIGINT to this process when item ``at`` is read (as Ctrl-C during that step)."""

    def __init__(self, dataset, n, at):
        super().__init__(dataset, n)
        self.at = at

    def __getitem__(self, i):
        if i == self.at:
            import os
            import signal
            os.kill(os.getpid(), signal.SIGINT)
        return super().__getitem__(i)


def test_interrupt_finishes_the_step_checkpoints_and_resumes(tiny_config, tiny_root, tmp_path):
    # batch_size 1 over a 4-item dataset: step s of epoch 0 reads permutation[s]; interrupt at step 1.
    from cerberus_core.train.data import step_indices

    data = Dataset.open(tiny_root).quadruplets()
    cfg = tiny_config("train.batch_size=1", "train.checkpoint_every=10", "train.image_every=0")
    at = step_indices(4, cfg.seed, 1, 1)[0]
    result = train(cfg, tmp_path / "run", dataset=InterruptAt(data, 4, at))
    assert result.interrupted and result.step == 2
    assert load_checkpoint(checkpoint_dir(tmp_path / "run") / "last.pt")["step"] == 2
    resumed = train(cfg, tmp_path / "run", resume=True, dataset=FirstItems(data, 4))
    straight = train(cfg, tmp_path / "straight", dataset=FirstItems(data, 4))
    assert resumed.step == 4 and not resumed.interrupted
    assert_same_weights(params(straight.model), params(resumed.model))


def test_a_step_still_running_after_sigterm_is_abandoned_within_its_grace(tiny_config, tiny_root, tmp_path,
                                                                          monkeypatch):
    """Issue 26: the first SIGTERM is honoured within seconds even inside a long step; the run keeps its
    last checkpoint."""
    import os
    import signal
    import time

    import cerberus_core.train.trainer as trainer_module
    from cerberus_core.plumbing.signals import Terminated

    monkeypatch.setattr(trainer_module, "STEP_GRACE_S", 0.3)
    original = trainer_module._Trainer._step

    def slow_second_step(self, batch, step):
        if step == 1:
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(30)  # a step that would outlive any patience
        return original(self, batch, step)

    monkeypatch.setattr(trainer_module._Trainer, "_step", slow_second_step)
    cfg = tiny_config("train.batch_size=1", "train.checkpoint_every=1", "train.image_every=0")
    start = time.monotonic()
    with pytest.raises(Terminated):
        train(cfg, tmp_path / "run", dataset=FirstItems(Dataset.open(tiny_root).quadruplets(), 4))
    assert time.monotonic() - start < 20
    assert load_checkpoint(checkpoint_dir(tmp_path / "run") / "last.pt")["step"] == 1
    assert signal.getsignal(signal.SIGTERM) is not trainer_module._StopRequest._handle  # handlers restored


def test_resources_a_setting_cannot_have_are_capped_or_refused(tiny_config, tiny_root, tmp_path):
    """Issue 26: threads beyond the cores are capped with a word; a batch larger than the data is refused
    before any step (it would repeat the data, and a huge one would never finish a step)."""
    import os

    from cerberus_core.errors import ConfigError

    before = torch.get_num_threads()
    try:
        cfg = tiny_config("threads=10000", "train.steps=1", "train.image_every=0")
        with pytest.warns(UserWarning, match=rf"threads=10000 is more than this machine's {os.cpu_count()} cores"):
            train(cfg, tmp_path / "run", dataset=FirstItems(Dataset.open(tiny_root).quadruplets(), 4))
        assert torch.get_num_threads() <= (os.cpu_count() or 1)
    finally:
        torch.set_num_threads(before)
    with pytest.raises(ConfigError, match=r"train.batch_size = 1000000000: more than the 4 quadruplets"):
        train(tiny_config("train.batch_size=1000000000"), tmp_path / "big", dataset=FirstItems(Dataset.open(tiny_root).quadruplets(), 4))


def test_adam_is_fused_and_loads_the_state_of_the_foreach_adam_before_it():
    """Issue 33: torch's fused Adam where torch has it (the CPU in torch >= 2.4), the same update up to
    rounding. A checkpoint written by the earlier foreach Adam loads, and its saved settings come with
    it, so a run started before the change resumes bit for bit as it would have."""
    import copy

    from cerberus_core.train.settings import OptimConfig
    from cerberus_core.train.trainer import fused_adam_devices, make_optimizer

    def net():
        torch.manual_seed(0)
        return torch.nn.Sequential(torch.nn.Linear(6, 5), torch.nn.Tanh(), torch.nn.Linear(5, 2))

    def steps(model, opt, n, seed):
        g = torch.Generator().manual_seed(seed)
        for _ in range(n):
            opt.zero_grad()
            model(torch.randn(4, 6, generator=g)).square().sum().backward()
            opt.step()

    cfg = OptimConfig(lr=1e-2, weight_decay=1e-3)
    fused = net()
    fused_opt = make_optimizer(fused, cfg)
    assert fused_opt.param_groups[0]["fused"] == ("cpu" in fused_adam_devices())
    old = net()
    old_opt = torch.optim.Adam(old.parameters(), lr=cfg.lr, betas=tuple(cfg.betas), eps=cfg.eps,
                               weight_decay=cfg.weight_decay)  # the optimiser before issue 33
    steps(fused, fused_opt, 3, 1)
    steps(old, old_opt, 3, 1)
    for a, b in zip(fused.parameters(), old.parameters(), strict=True):
        torch.testing.assert_close(a, b, atol=1e-6, rtol=1e-5)
    resumed = net()
    resumed.load_state_dict(old.state_dict())
    resumed_opt = make_optimizer(resumed, cfg)
    resumed_opt.load_state_dict(copy.deepcopy(old_opt.state_dict()))  # as from a checkpoint file
    steps(resumed, resumed_opt, 2, 2)
    steps(old, old_opt, 2, 2)
    assert all(torch.equal(a, b) for a, b in zip(resumed.parameters(), old.parameters(), strict=True))


def test_settings_the_machine_cannot_honour_are_refused_before_anything_is_allocated(tiny_config, tiny_root, tmp_path):
    """Issue 34: a training whose memory estimate exceeds the machine's is one ConfigError naming the setting,
    the estimate and the limit, from ``train()`` itself, before the run folder exists; worker processes beyond
    the cores are lowered to them with a word, like threads."""
    import os

    from cerberus_core.errors import ConfigError
    from cerberus_core.plumbing.machine import memory_bytes, size_text

    many = FirstItems(Dataset.open(tiny_root).quadruplets(), 100_000)  # no item is read: the refusal comes first
    cfg = tiny_config("data.image_size=4096", "model.width=1024", "train.batch_size=1000", "train.steps=1")
    with pytest.raises(ConfigError, match=rf"data.image_size = 4096: needs at least .* of memory \(4000 images of "
                       rf"4096x4096 pixels per step at train.batch_size = 1000\), more than the "
                       rf"{size_text(memory_bytes())} this machine has; choose a smaller `data.image_size`"):
        train(cfg, tmp_path / "run", dataset=many)
    assert not (tmp_path / "run").exists()
    with pytest.raises(ConfigError, match="model.num_parts = 64: needs at least .* 20480 faces per step"):
        train(tiny_config("model.num_parts=64", "model.sphere_level=5", "train.batch_size=1000"), tmp_path / "run",
              dataset=many)
    assert not (tmp_path / "run").exists()
    with pytest.raises(ConfigError, match=r"model.width = 100000: needs at least .* of memory \(about .* million weights"):
        train(tiny_config("model.width=100000"), tmp_path / "run", dataset=many)  # was a 360 GB allocation
    with pytest.raises(ConfigError, match=r"model.shape_latent_dim = 100000000: needs at least"):
        train(tiny_config("model.shape_latent_dim=100000000"), tmp_path / "run", dataset=many)
    assert not (tmp_path / "run").exists()
    cores = len(os.sched_getaffinity(0))
    with pytest.warns(UserWarning, match=rf"data.num_workers=200 is more than this machine's {cores} cores"):
        result = train(tiny_config("data.num_workers=200", "train.steps=1", "train.image_every=0"), tmp_path / "w",
                       dataset=FirstItems(Dataset.open(tiny_root).quadruplets(), 4))
    assert Run.load(result.run_dir).config.data.num_workers == cores


def test_a_resume_may_not_shorten_the_run(tiny_config, tmp_path):
    """Issue 34: resuming with ``train.steps`` below the step reached would rewrite the run's config to fewer steps
    than it ran; refused, the run left as it was."""
    from cerberus_core.errors import ConfigError

    train(tiny_config("train.steps=2", "train.image_every=0"), tmp_path / "run")
    before = {p: p.stat().st_mtime_ns for p in (tmp_path / "run").rglob("*")}
    with pytest.raises(ConfigError, match=r"train.steps = 1: the run in .* already reached step 2; a resumed run "
                       r"cannot end before it \(`train.steps=2` or more"):
        train(tiny_config("train.steps=1", "train.image_every=0"), tmp_path / "run", resume=True)
    assert {p: p.stat().st_mtime_ns for p in (tmp_path / "run").rglob("*")} == before


def test_allocation_is_logged_on_a_fixed_test_batch_and_leaves_the_training_as_it_was(tiny_config, tmp_path):
    probed = train(tiny_config("train.allocation_every=2"), tmp_path / "probed")
    plain = train(tiny_config("train.allocation_every=0"), tmp_path / "plain")
    assert_same_weights(params(probed.model), params(plain.model))  # eval mode, no gradient, no RNG drawn
    logged = {r["step"]: r for r in rows(tmp_path / "probed")}
    for step in ("2", "4"):
        assert 0 <= float(logged[step]["keypoint_spread_max"]) < 32  # pixels of the 32-px images
        assert float(logged[step]["keypoint_spread_top4"]) <= float(logged[step]["keypoint_spread_max"])
        assert 0 <= float(logged[step]["segment_to_keypoint_mean"]) <= float(logged[step]["segment_to_keypoint_max"])
        assert float(logged[step]["low_coverage_parts"]).is_integer()
    assert logged["1"]["keypoint_spread_max"] == logged["3"]["keypoint_spread_max"] == ""
    assert all(r["keypoint_spread_max"] == "" for r in rows(tmp_path / "plain"))


def test_the_input_look_changes_what_the_network_sees_and_is_a_function_of_the_step(tiny_config, tmp_path):
    shaded = params(train(tiny_config("train.steps=2", "train.image_every=0"), tmp_path / "shaded").model)
    looks = [params(train(tiny_config("train.steps=2", "train.image_every=0", "data.input_look=random"),
                          tmp_path / name).model) for name in ("a", "b")]
    assert_same_weights(*looks)  # the random appearances are drawn from (seed, step, rank)
    assert any(not torch.equal(shaded[k], looks[0][k]) for k in shaded)
    assert "input_look: random" in (tmp_path / "a" / "config.yaml").read_text()


def test_a_checkpoint_written_before_issue_40_loads_and_resumes_with_the_same_config(tmp_path):
    """tests/core/train/data/checkpoint_57eefd7.pt was written by commit 57eefd7 (before LossConfig was a written
    class and the saved config had one reader): a 2-part, width-4 model at step 3, losses.coverage=0.5. Its config
    reads back to the same YAML (so a resume sees no changed key), the resume check accepts it, and it loads as a
    run with its weights."""
    import shutil

    from cerberus_core.train.settings import TrainConfig, config_diff
    from cerberus_core.train.trainer import prepare_run_dir

    run_dir = tmp_path / "run"
    checkpoint_dir(run_dir).mkdir(parents=True)
    last = checkpoint_dir(run_dir) / "last.pt"
    shutil.copyfile(Path(__file__).parent / "data" / "checkpoint_57eefd7.pt", last)
    payload = load_checkpoint(last)
    config = TrainConfig.from_yaml(payload["config"], last)
    import yaml

    from cerberus_core.config import upgrade

    def holds(new, old):  # every setting the old config had, with its value (later settings may be added)
        return all(holds(new[k], v) if isinstance(v, dict) else new.get(k) == v for k, v in old.items())
    old = yaml.safe_load(payload["config"])  # renamed keys under their new names (model.predict_rotation: true)
    assert old["model"]["predict_rotation"] is True and "rotation" not in old["model"]
    assert holds(yaml.safe_load(config.to_yaml()), upgrade(TrainConfig, old)) and config.losses.coverage == 0.5
    assert config.model.rotation == "camera"
    assert config_diff(config, TrainConfig.from_yaml(config.to_yaml(), "again")) == []
    assert prepare_run_dir(run_dir, True, config)["step"] == 3
    run = Run.load(last)
    assert run.step == 3 and run.model.config.num_parts == 2
    for name, tensor in run.model.state_dict().items():
        assert torch.equal(tensor, payload["model"][name]), name
