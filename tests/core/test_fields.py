"""cerberus_core.fields: ranges and choices declared as data, checked where a settings object is made."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import pytest

from cerberus_core.errors import ConfigError, InputTypeError
from cerberus_core.fields import Checked, Range, check_fields, check_kind, check_path, check_paths, ranged


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
            raise ConfigError.about("example.mode", self.mode, "needs example.steps >= 5")


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


@pytest.mark.parametrize(("call", "words"), [
    (lambda: check_path("out", None), "out: got NoneType None; pass a path"),
    (lambda: check_path("out", 5), "out: got int 5; pass a path"),
    (lambda: check_path("out", ""), "out: got str ''; pass a path"),
    (lambda: check_path("out", b"x"), "out: got bytes b'x'; pass a path"),
    (lambda: check_paths("images", "a.png"), r"images: got str 'a.png'; pass a list of paths \(e.g. \[image\]\)"),
    (lambda: check_paths("images", None), "images: got NoneType None; pass a list of paths"),
    (lambda: check_paths("images", [Path("a.png"), 3]), r"images\[1\]: got int 3; pass a path"),
    (lambda: check_kind("settings", {}, Example, "an Example"), "settings: got dict {}; pass an Example"),
], ids=["none", "int", "empty", "bytes", "one-str", "images-none", "item", "kind"])
def test_a_parameter_of_the_wrong_kind_is_one_input_type_error_naming_it(call, words):
    """Issue 34 campaign: ``Run.load(None)``, ``reconstruct_images("a.png", ...)`` (read one character at a time) and
    ``evaluate(settings={...})`` ended in a TypeError or AttributeError naming no parameter."""
    with pytest.raises(InputTypeError, match=words):
        call()


def test_paths_are_taken_as_str_or_path_like():
    assert check_path("out", "a/b") == Path("a/b") and check_path("out", Path("c")) == Path("c")
    assert check_paths("images", ("a.png", Path("b.png"))) == [Path("a.png"), Path("b.png")]
