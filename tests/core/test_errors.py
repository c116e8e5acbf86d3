"""The toolkit's errors (cerberus_core.errors): a missing optional package is a CerberusError naming the extra."""
from __future__ import annotations

import pytest


def test_a_missing_optional_package_is_a_toolkit_error_naming_the_extra(monkeypatch) -> None:
    import sys

    from cerberus_core.errors import CerberusError, MissingPackageError

    monkeypatch.setitem(sys.modules, "anny", None)  # import anny -> ImportError
    from cerberus_core.bodies.human import HumanBodySource
    with pytest.raises(MissingPackageError, match=r"pip install 'cerberus-core\[human\]'") as err:
        HumanBodySource()
    assert isinstance(err.value, CerberusError) and isinstance(err.value, ImportError)


def test_a_typed_error_is_still_the_builtin_it_replaced() -> None:
    """The sweep of issue 32 kept ``except ValueError`` / ``except TypeError`` callers working."""
    from cerberus_core.errors import CerberusError, MeshError, RenderInputError, TrainingDatasetError
    from cerberus_core.render.camera import Camera
    from cerberus_core.render.templates import MeshTemplate
    from cerberus_core.train.data import check_dataset

    with pytest.raises(RenderInputError, match="distance must be positive; place the camera") as err:
        Camera.look_at(0.0, 0.0, -1.0)
    assert isinstance(err.value, ValueError)
    import trimesh
    with pytest.raises(MeshError, match="at least one face") as err:
        MeshTemplate.from_trimesh(trimesh.Trimesh())
    assert isinstance(err.value, ValueError)
    with pytest.raises(TrainingDatasetError, match=r"lacks \['image_size', 'scene'") as err:
        check_dataset([])
    assert isinstance(err.value, TypeError) and isinstance(err.value, CerberusError)
