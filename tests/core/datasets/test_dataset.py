"""A dataset as one object (cerberus_core.datasets.dataset): a generation asked for as a request (what
``cerberus data generate`` passes) is the generation of its config, and a dataset's own request rebuilds it; the
object's own checks of its arguments (opening, reading and generating are tested with the modules that do them:
test_manifest, test_readers, test_generate)."""
from __future__ import annotations

import pytest

from cerberus_core.datasets.dataset import Dataset
from cerberus_core.datasets.format import sha256_file
from cerberus_core.datasets.plan import GenerationRequest
from cerberus_core.errors import ConfigError, InputTypeError
from tests.support.paths import REPO

QUIET = {"progress": False, "log": lambda s: None}


def _fingerprint(root) -> dict[str, str]:
    return {p.relative_to(root).as_posix(): sha256_file(p) for p in sorted(root.rglob("*")) if p.is_file()}


def test_a_request_generates_what_its_config_generates(tiny_root, tmp_path):
    """``tiny_root`` is ``Dataset.generate(preset_config("primitives", "tiny", image_size=32), ...)``."""
    request = GenerationRequest("primitives", "tiny", {"image_size": 32})
    assert Dataset.plan(request).plan_lines() == Dataset.plan(request.config()).plan_lines()
    made = Dataset.generate(request, tmp_path / "ds", **QUIET)
    assert _fingerprint(made.root) == _fingerprint(tiny_root)
    again = made.request()  # the stored config: the renderer `auto` resolved to the backend used
    assert again == Dataset.open(tiny_root).request() and again.overrides["image_size"] == 32


def test_source_options_come_one_way_in_the_request(tmp_path):
    """A body source's options travel in the GenerationRequest alone: there is no second parameter for them."""
    import inspect

    assert "source_options" not in inspect.signature(Dataset.generate).parameters
    assert "source_options" not in inspect.signature(Dataset.plan).parameters
    with pytest.raises(ConfigError, match="not an option of the primitives body source") as caught:
        Dataset.plan(GenerationRequest("primitives", "tiny", source_options={"a": 1}), tmp_path / "ds")
    assert caught.value.key == "a" and not (tmp_path / "ds").exists()


@pytest.mark.parametrize(("call", "words"), [
    (lambda tmp: Dataset.open(None), "root: got NoneType None"),
    (lambda tmp: Dataset.generate(None, tmp / "out"), "config: got NoneType None; pass a GenerationRequest or a GenerationConfig"),
    (lambda tmp: Dataset.generate({"dataset": "primitives"}, tmp / "out"), "config: got dict"),
    (lambda tmp: Dataset.plan({"dataset": "primitives"}), "config: got dict"),
], ids=["open-none", "generate-none", "generate-dict", "plan-dict"])
def test_an_argument_of_the_wrong_kind_is_named(tmp_path, call, words):
    """Issue 34 campaign: these were a TypeError or AttributeError ('dict' object has no attribute 'dataset')."""
    with pytest.raises(InputTypeError, match=words):
        call(tmp_path)
    assert list(tmp_path.iterdir()) == []


def test_contact_sheet_names_an_out_of_the_wrong_kind(pairs_dataset):
    with pytest.raises(InputTypeError, match="out: got int 3"):
        Dataset.open(pairs_dataset).contact_sheet(3)


def test_the_readers_are_made_by_dataset_alone():
    """QuadrupletDataset and ViewDataset are reached through Dataset.quadruplets / Dataset.views: no other module of
    the packages, experiments, benchmarks or tests makes one (read with ast, nothing imported)."""
    import ast

    made = []
    for folder in ("packages", "experiments", "benchmarks", "tests"):
        for path in sorted((REPO / folder).rglob("*.py")):
            if path.name == "dataset.py" and path.parent.name == "datasets":
                continue
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
                        and node.func.id in ("QuadrupletDataset", "ViewDataset")):
                    made.append(f"{path.relative_to(REPO)}:{node.lineno}")
    assert not made, "open the dataset and ask it: Dataset.open(root).quadruplets(split) or .views(split):\n" + "\n".join(made)
