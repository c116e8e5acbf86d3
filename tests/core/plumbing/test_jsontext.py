"""cerberus_core.plumbing.jsontext: every way JSON text from outside is malformed is one ValueError."""
import json

import pytest

from cerberus_core.plumbing import jsontext


@pytest.mark.parametrize(("text", "words"), [
    ("{", "Expecting property name"),
    ("[" * 100_000 + "]" * 100_000, "nested too deeply to be read"),
    ("1" * 5000, "holds a number of more than 4300 digits"),
], ids=["syntax", "deep", "long-number"])
def test_every_malformed_text_is_a_value_error_saying_what(text, words):
    with pytest.raises(ValueError, match=words):
        jsontext.loads(text)


def test_well_formed_text_reads_as_json_does():
    text = '{"a": [1, 2.5, null, "x"], "b": {"c": true}}'
    assert jsontext.loads(text) == json.loads(text)
