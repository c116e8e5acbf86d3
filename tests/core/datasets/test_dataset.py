"""cerberus_core.datasets.dataset: the Dataset object's own checks of its arguments (opening, reading and
generating are tested with the modules that do them: test_manifest, test_readers, test_generate)."""
import pytest

from cerberus_core.datasets.dataset import Dataset
from cerberus_core.errors import InputTypeError


@pytest.mark.parametrize(("call", "words"), [
    (lambda tmp: Dataset.open(None), "root: got NoneType None"),
    (lambda tmp: Dataset.generate(None, tmp / "out"), "config: got NoneType None; pass a GenerationConfig"),
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
