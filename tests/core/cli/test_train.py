"""``cerberus train`` end to end: start, refuse to clobber, resume, report errors with exit codes."""
import pytest
import yaml

from cerberus_core.cli import main

pytestmark = pytest.mark.usefixtures("one_thread")  # as tests/core/train/conftest.py does


def test_cli_trains_resumes_and_reports(tiny_root, tmp_path, capsys):
    out = tmp_path / "run"
    common = ["train", "--preset", "tiny", "--set", f"data.root={tiny_root}", "--set", "train.tensorboard=false",
              "--out", str(out)]
    assert main([*common, "--set", "train.steps=2"]) == 0
    assert "finished step 2" in capsys.readouterr().out
    saved = yaml.safe_load((out / "config.yaml").read_text())
    assert saved["train"]["steps"] == 2 and isinstance(saved["model"]["depth_offset"], float)
    assert main([*common, "--set", "train.steps=2"]) == 2
    assert "--resume" in capsys.readouterr().err
    # resume from the run's own config, extending the schedule
    assert main(["train", "--out", str(out), "--resume", "--set", "train.steps=3"]) == 0
    assert "finished step 3" in capsys.readouterr().out


def test_cli_errors_are_short_and_name_the_fix(tiny_root, tmp_path, capsys):
    assert main(["train", "--preset", "tiny", "--set", "optim.lr=fast"]) == 2
    assert "optim.lr: expected a number" in capsys.readouterr().err
    assert main(["train", "--preset", "tiny", "--out", str(tmp_path / "none"), "--resume"]) == 2
    assert "no checkpoint" in capsys.readouterr().err
    assert main(["train", "--preset", "tiny", "--set", f"data.root={tiny_root}", "--set", "debug.poison_steps=[0]",
                 "--set", "train.tensorboard=false", "--out", str(tmp_path / "nan")]) == 3
    assert "non-finite" in capsys.readouterr().err


def test_print_config_resolves_presets(capsys):
    assert main(["train", "--preset", "free_cerberus", "--print-config"]) == 0
    cfg = yaml.safe_load(capsys.readouterr().out)
    assert cfg["losses"]["pose_consistency"] is False and cfg["model"]["num_parts"] == 9
    assert main(["train", "--preset", "cpu", "--preset", "nmrr", "--print-config"]) == 0
    cfg = yaml.safe_load(capsys.readouterr().out)
    assert cfg["model"]["num_parts"] == 1 and cfg["model"]["width"] == 32 and cfg["train"]["steps"] == 10000


def test_renderer_is_a_flag_like_device(capsys):
    """Issue 34: `cerberus train --renderer NAME` is `--set renderer=NAME`, as on the other commands."""
    assert main(["train", "--preset", "tiny", "--renderer", "torch", "--print-config"]) == 0
    assert "renderer: torch" in capsys.readouterr().out
