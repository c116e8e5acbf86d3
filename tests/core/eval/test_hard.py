"""Hard Human's choice of the canonical view (cerberus_core.eval.hard)."""
from __future__ import annotations

import pytest

from cerberus_core.errors import CerberusError, UnknownSubjectError
from cerberus_core.eval.hard import CanonicalParts, ItemMeta, select_canonical
from tests.support.oracle import random_partset


def test_select_canonical_prefers_lowest_view_and_skips_subjects_without_one():
    items = [ItemMeta(0, "a", 3, 0, False), ItemMeta(1, "a", 0, 2, True), ItemMeta(2, "a", 0, 1, True),
             ItemMeta(3, "b", 5, 0, False), ItemMeta(4, "c", 0, 0, True)]
    assert select_canonical(items) == {"a": 2, "c": 4}
    assert select_canonical(items, view=2) == {"a": 1}
    canon = CanonicalParts({"a": random_partset(1, 2, 0)}, {"a": 2})
    assert canon.applies_to(items[1]) and not canon.applies_to(items[2]) and not canon.applies_to(items[3])


def test_posing_a_subject_without_a_canonical_image_names_it_and_the_fix():
    canon = CanonicalParts({"a": random_partset(1, 2, 0)}, {"a": 2})
    assert canon.pose("a", random_partset(3, 2, 1)).batch_size == 3
    with pytest.raises(UnknownSubjectError) as caught:
        canon.pose("b", random_partset(1, 2, 1))
    message = str(caught.value)  # said as it is, not as KeyError's repr
    assert message.startswith("CanonicalParts.pose: no canonical image of subject 'b' (those with one: 'a')")
    assert "`applies_to(item)`" in message and isinstance(caught.value, (CerberusError, KeyError))
