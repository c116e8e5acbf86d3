"""Names from outside in what the toolkit prints and writes (cerberus_core.plumbing.names, issue 20): terminal
text never carries control characters, output stems are valid and short, close matches are suggested."""
from __future__ import annotations

import os

from cerberus_core.eval.markdown import md_text
from cerberus_core.plumbing.names import MAX_STEM_BYTES, did_you_mean, printable, safe_stem


def test_md_text_and_printable() -> None:
    assert md_text("a&b") == "a&amp;b"
    assert printable("ok \x1b[2J\r\n\u202e") == "ok \\x1b[2J\\r\\n\\u202e"
    assert printable(os.fsdecode(b"caf\xe9")) == "caf\\xe9"
    assert printable("café ü") == "café ü"


def test_safe_stem_is_short_valid_and_distinct() -> None:
    assert safe_stem(os.fsdecode(b"caf\xe9")) == "caf_"
    assert safe_stem("\x1b[31mred") == "_[31mred"
    assert safe_stem("..hidden") == "hidden" and safe_stem("") == "image"
    long_a, long_b = "é" * 200 + "a", "é" * 200 + "b"
    a, b = safe_stem(long_a), safe_stem(long_b)
    assert a != b and len(a.encode()) <= MAX_STEM_BYTES and len(b.encode()) <= MAX_STEM_BYTES
    a.encode("utf-8")



def test_did_you_mean_finds_case_and_typos_and_nothing_far():
    assert did_you_mean("Warp", ["torch", "warp"]) == " (did you mean 'warp'?)"
    assert did_you_mean("humna", ["human", "animal"]) == " (did you mean 'human'?)"
    assert did_you_mean(7, [8, 17]) == " (did you mean '17'?)"  # a YAML key or value may be a number
    assert did_you_mean("zzz", ["human", "animal"]) == ""
    assert did_you_mean("warp", ["warp"]) == ""
