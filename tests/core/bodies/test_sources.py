"""Body sources by name (cerberus_core.bodies.sources)."""
from __future__ import annotations

import numpy as np
import pytest

from cerberus_core.errors import DatasetError


@pytest.mark.parametrize("name", ["primitives", "animal"])
def test_sources_are_stateless(name):
    """A body depends only on (subject record, pose id): a fresh source, a JSON round trip of the
    record and another batch of ids give the same mesh, without calling subjects() first."""
    import json

    from cerberus_core.bodies.body import Subject, source_class
    from cerberus_core.datasets.manifest import SubjectRecord

    src = source_class(name)()
    subject = src.subjects("test", 2, 3)[1]
    pose = src.pose_pool(subject, "test", 1)[0]
    expected = src.bodies(subject, [pose])[0]
    stored = json.loads(json.dumps(SubjectRecord(subject.name, subject.info).to_json()))  # as the manifest keeps it
    again = source_class(name)().bodies(SubjectRecord.from_json(stored).subject, [pose])[0]
    np.testing.assert_array_equal(again.vertices, expected.vertices)
    np.testing.assert_array_equal(again.vertex_parts, expected.vertex_parts)
    with pytest.raises(DatasetError, match="rerun the same"):
        src.bodies(Subject(subject.name), [pose])
