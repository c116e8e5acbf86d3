"""cerberus_core/cli/flags.py: FlagNames says the settings the library names as the command's flags."""
from __future__ import annotations


def test_flag_names_say_the_library_settings_as_the_command_flags():
    """The library names settings in Python terms; the CLI's one translation says each as the flag of the
    command that was run (typed, or the command's only way to set it), else ``--set KEY=VALUE``."""
    from cerberus_core.cli.flags import FlagNames, typed_flags
    from cerberus_core.errors import ConfigError
    from cerberus_core.train.settings import TrainConfig

    names = FlagNames({"run_dir": "--out", "resume": "--resume", "device": "--device", "masks": "--mask"}, TrainConfig,
                      typed_flags(["train", "--out=runs/a", "--set", "device=cuda"]))
    assert names.text("pass `resume=True`, or another `run_dir`; or `resume=False`") == \
        "pass --resume, or another --out; or without --resume"
    assert names.text("e.g. `masks=DIR` or `train.steps=10`; see `train.steps`") == \
        "e.g. --mask DIR or --set train.steps=10; see train.steps"
    assert names.text("`canonical` and `cerberus data generate` stay") == "`canonical` and `cerberus data generate` stay"
    # a config key with a flag of its own: the flag where it was typed, else --set
    cuda = ConfigError.about("device", "cuda", "CUDA is not available on this machine; use `device=cpu`")
    assert names.error(cuda) == "device = 'cuda': CUDA is not available on this machine; use --set device=cpu"
    typed = FlagNames(names.flags, TrainConfig, typed_flags(["train", "--device", "cuda"]))
    assert typed.error(cuda) == "--device cuda: CUDA is not available on this machine; use --device cpu"
    steps = ConfigError.about("train.steps", 0, "must be an integer >= 1", "`train.steps=VALUE`")
    assert str(steps) == "train.steps = 0: must be an integer >= 1 (`train.steps=VALUE`)"
    assert names.error(steps) == "train.steps = 0: must be an integer >= 1 (--set train.steps=VALUE)"
    assert FlagNames().error(steps) == str(steps)  # a command without --set or flags leaves the library's words
    bad = ConfigError.about("overrides", "a.b=[1", "not valid YAML")
    assert FlagNames({"overrides": "--set"}).error(bad) == "--set 'a.b=[1': not valid YAML"
