"""cerberus_core.fields: ranges and choices declared as data, checked where a settings object is made."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import pytest

from cerberus_core.errors import ConfigError
from cerberus_core.fields import Checked, Range, check_fields, ranged


@dataclass
class Example(Checked):
    SECTION = "example"
    lr: float = ranged(0.5, gt=0)
    steps: int = ranged(10, ge=1)
    ratio: float = ranged(0.1, ge=0, lt=1)
    mode: Literal["a", "b"] = "a"
    maybe: Literal["x"] | None = None
    free: int | None = ranged(None, ge=1, integer=True)

    def validate(self) -> None:
        if self.mode == "b" and self.steps < 5:
            raise ConfigError("example.mode = 'b' needs example.steps >= 5")


@pytest.mark.parametrize(("rng", "text"), [
    (Range(gt=0), "a number > 0"), (Range(ge=1, integer=True), "an integer >= 1"),
    (Range(ge=0, lt=1), "a number in [0, 1)"), (Range(le=2), "a number <= 2"), (Range(), "a finite number"),
])
def test_range_describes_itself(rng, text):
    assert rng.describe() == text


def test_range_admits_only_finite_numbers_inside_and_wholes_where_asked():
    r = Range(ge=1, integer=True)
    assert r.admits(1) and r.admits(None) and not r.admits(0) and not r.admits(1.5) and not r.admits(True)
    assert not Range().admits(float("nan")) and not Range().admits(float("inf")) and not Range().admits("3")
    assert Range(gt=0).admits(1e-9) and not Range(gt=0).admits(0) and not Range(lt=1).admits(1)


def test_ranged_infers_integer_from_the_default():
    assert Example.__dataclass_fields__["steps"].metadata["cerberus.range"].integer
    assert not Example.__dataclass_fields__["lr"].metadata["cerberus.range"].integer


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"lr": 0}, r"example.lr = 0: must be a number > 0 \(`example.lr=VALUE`\)"),
    ({"steps": 2.5}, r"example.steps = 2.5: must be an integer >= 1"),
    ({"ratio": 1.0}, r"example.ratio = 1.0: must be a number in \[0, 1\)"),
    ({"mode": "c"}, r"example.mode = 'c': must be one of 'a', 'b'"),
    ({"maybe": "y"}, r"example.maybe = 'y': must be one of 'x', null"),
    ({"free": 0}, r"example.free = 0: must be an integer >= 1"),
    ({"mode": "b", "steps": 2}, r"needs example.steps >= 5"),  # validate() runs after the ranges
])
def test_construction_checks_every_field_and_names_the_key_and_the_fix(kwargs, message):
    with pytest.raises(ConfigError, match=message):
        Example(**kwargs)


def test_a_field_changed_in_place_is_checked_again_by_check():
    ex = Example(maybe="x", free=3)
    ex.lr = -1.0
    with pytest.raises(ConfigError, match="example.lr"):
        ex.check()
    check_fields(Example(), "")  # a section-less check names the bare key
    ex.lr = 0
    with pytest.raises(ConfigError, match=r"^lr = 0"):
        check_fields(ex)
