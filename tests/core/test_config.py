"""cerberus_core.config: the one reader of settings text (issue 39: aliases, YAML 1.2 numbers, echoed values)."""
from __future__ import annotations

import pytest

from cerberus_core.config import load_yaml, parse_overrides
from cerberus_core.datasets.plan import GenerationRequest
from cerberus_core.errors import ConfigError, InputTypeError
from cerberus_core.train.settings import load_config


def test_aliases_are_refused_before_they_expand():
    """A 400-byte ``--set train.steps=`` value of nested aliases made a 17.5 MB error line at 7 levels."""
    levels = ["a0: &a0 [x, x, x, x, x, x, x, x, x]"] + [f"a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * 9) + "]"
                                                        for i in range(1, 8)]
    bomb = "{" + ", ".join(levels) + "}"
    with pytest.raises(ConfigError, match=r"^overrides = .{1,100}: the value is not valid YAML \(an alias \(\*a0\) "
                       r"repeats another value; settings take no aliases") as err:
        parse_overrides([f"train.steps={bomb}"])
    assert len(str(err.value)) < 400
    with pytest.raises(ConfigError, match=r"^config:2: not valid YAML \(an alias"):
        load_yaml("a: &x 1\nb: *x")
    assert load_yaml("a: &x 1") == {"a": 1}  # an anchor alone repeats nothing


@pytest.mark.parametrize(("text", "value"), [("010", 10), ("-010", -10), ("0o10", 8), ("0x10", 16), ("1:30", "1:30"),
                                             ("5e-4", 5e-4), ("1.0e-05", 1e-05), ("1_000", "1_000"), ("true", True)])
def test_numbers_are_read_as_yaml_1_2_reads_them(text, value):
    """``--set train.steps=010`` trained 8 steps and ``1:30`` 90 (YAML 1.1's octal and sexagesimal)."""
    assert load_yaml(text) == value and type(load_yaml(text)) is type(value)


def test_train_steps_010_is_ten_and_1_30_is_refused():
    assert load_config(None, preset="tiny", overrides=["train.steps=010"]).train.steps == 10
    with pytest.raises(ConfigError, match=r"^train.steps: expected an integer, got '1:30'$"):
        load_config(None, preset="tiny", overrides=["train.steps=1:30"])


def test_a_long_value_is_echoed_cut():
    with pytest.raises(ConfigError) as err:
        load_config(None, preset="tiny", overrides=["train.steps=" + "x" * 100_000])
    assert str(err.value).startswith("train.steps: expected an integer, got 'xxx") and len(str(err.value)) < 200


def test_a_generation_request_checks_its_fields():
    """``overrides`` as a list or a string was an AttributeError; a key ``"splits.train.pairs=2 #"`` was accepted."""
    for overrides in ([("seed", 1)], "seed=1"):
        with pytest.raises(InputTypeError, match="^overrides: got .*; pass a mapping of config keys to values"):
            GenerationRequest("primitives", "tiny", overrides)
    with pytest.raises(ConfigError, match=r"^overrides = 'splits.train.pairs=2 #': is not a config key"):
        GenerationRequest("primitives", "tiny", {"splits.train.pairs=2 #": 1})
    with pytest.raises(InputTypeError, match="^source_options: got int 5"):
        GenerationRequest("primitives", "tiny", {}, 5)
    with pytest.raises(InputTypeError, match="^dataset: got NoneType None"):
        GenerationRequest(None)
    assert GenerationRequest("primitives", "tiny", {"splits.train.pairs": 2}).config().splits["train"].pairs == 2
