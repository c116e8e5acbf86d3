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
