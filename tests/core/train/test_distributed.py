"""Data-parallel training: 2 CPU processes (gloo) end with identical weights, also across a skipped
(non-finite) step, which every rank must agree to skip."""
import socket

import pytest
import torch
import torch.multiprocessing as mp


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _worker(rank: int, world: int, port: int, root: str, run_dir: str, out: str, extra: tuple[str, ...]) -> None:
    import os

    os.environ.update(MASTER_ADDR="127.0.0.1", MASTER_PORT=str(port), RANK=str(rank), WORLD_SIZE=str(world),
                      LOCAL_RANK=str(rank))
    torch.set_num_threads(1)
    from cerberus_core.train import load_config, train

    cfg = load_config(preset="tiny", overrides=[f"data.root={root}", "train.tensorboard=false", "train.steps=3",
                                                "train.batch_size=4", "train.image_every=0",
                                                "train.on_nonfinite=skip", "debug.poison_steps=[1]", *extra])
    result = train(cfg, run_dir)
    params = {k: v.detach().clone() for k, v in result.model.named_parameters()}
    torch.save({"params": params, "step": result.step, "skipped": result.skipped}, f"{out}/rank{rank}.pt")


@pytest.mark.slow
@pytest.mark.parametrize("extra", [(), ("model.rotation=none",)], ids=["camera", "rotation_none"])
def test_two_processes_keep_identical_weights(tiny_root, tmp_path, extra):
    """``rotation: none`` leaves the rotation head without gradient: DDP must be told to look for it."""
    from cerberus_core.model import Cerberus
    from cerberus_core.run import Run
    from cerberus_core.train import load_config

    mp.start_processes(_worker, args=(2, _free_port(), str(tiny_root), str(tmp_path / "run"), str(tmp_path), extra),
                       nprocs=2, join=True, start_method="spawn")
    a = torch.load(tmp_path / "rank0.pt", weights_only=True)
    b = torch.load(tmp_path / "rank1.pt", weights_only=True)
    assert a["step"] == b["step"] == 3 and a["skipped"] == b["skipped"] == 1
    for k in a["params"]:
        assert torch.equal(a["params"][k], b["params"][k]), k
    saved = Run.load(tmp_path / "run").model
    for k, v in saved.named_parameters():
        assert torch.equal(v, a["params"][k]), k
    # training moved the weights away from the (seeded) initialisation
    cfg = load_config(preset="tiny")
    cfg.model.depth_offset = saved.config.depth_offset
    torch.manual_seed(cfg.seed)
    init = dict(Cerberus(cfg.model).named_parameters())
    assert not torch.equal(init["shape.to_displacement.weight"], a["params"]["shape.to_displacement.weight"])
    # without rotations the head is not run: it keeps its initial weights
    assert torch.equal(init["rotation.linear.weight"], a["params"]["rotation.linear.weight"]) == bool(extra)


@pytest.mark.parametrize(("env", "words"), [
    ({"WORLD_SIZE": "2"}, "RANK is unset, not a whole number 0 or more below 2"),
    ({"LOCAL_RANK": "abc"}, "LOCAL_RANK is 'abc', not a whole number"),
    ({"WORLD_SIZE": "0"}, "WORLD_SIZE is '0', not a whole number 1 or more"),
    ({"WORLD_SIZE": "2", "RANK": "5"}, "RANK is '5', not a whole number 0 or more below 2"),
], ids=["no-rank", "local-text", "world-zero", "rank-beyond"])
def test_a_launch_environment_set_by_hand_is_named(monkeypatch, env, words):
    """Issue 34 campaign: WORLD_SIZE=2 without RANK was a KeyError traceback, LOCAL_RANK=abc a ValueError."""
    from cerberus_core.errors import ConfigError
    from cerberus_core.train.distributed import launch_environment

    for name in ("WORLD_SIZE", "RANK", "LOCAL_RANK"):
        monkeypatch.delenv(name, raising=False)
    assert launch_environment().world_size == 1
    for name, value in env.items():
        monkeypatch.setenv(name, value)
    with pytest.raises(ConfigError, match=words):
        launch_environment()
