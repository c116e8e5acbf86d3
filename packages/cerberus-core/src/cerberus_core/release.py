"""Which release of the Cerberus toolkit this is, and the lock-step check between its packages.

The toolkit's four distributions (:data:`DISTRIBUTIONS`) are released together under one version,
:data:`VERSION`, and each requires its siblings at exactly that version. The version carries the
local label ``+toolkit``, which the public package index refuses to host (PyPI rejects every upload
with a local version label), so no requirement of ours can be satisfied by the unrelated project that
owns the name ``cerberus-core`` there: an install without our wheelhouse fails with "no matching
distribution" instead of bringing in a stranger's code. Install from the wheelhouse that
``scripts/wheelhouse.sh`` builds (README, "Installing with pip").

A backend checks, when it is imported, that the ``cerberus-core`` it finds is this release
(:func:`require_lockstep`); one that finds another project under that import name says so in one line.
"""
from __future__ import annotations

from cerberus_core.errors import ReleaseMismatchError

VERSION = "0.2.0+toolkit"
"""The version of every distribution of this release (``pyproject.toml`` of each package)."""

DISTRIBUTIONS: tuple[str, ...] = ("cerberus-core", "cerberus-render-torch", "cerberus-render-warp", "cerberus-metrics")
"""The toolkit's distributions, released in lock-step."""

INSTALL_HINT = ("install the toolkit's packages together from one wheelhouse: bash scripts/wheelhouse.sh, then "
                "pip install --find-links dist/wheelhouse -c dist/wheelhouse/constraints.txt cerberus-core ... "
                "(README, 'Installing with pip')")


def installed_version(distribution: str) -> str | None:
    """The installed version of ``distribution`` (``None`` if it is not installed)."""
    from importlib import metadata  # here: `import cerberus_core` stays free of it (the CLI's first moments)

    try:
        return metadata.version(distribution)
    except metadata.PackageNotFoundError:
        return None


def require_lockstep(distribution: str) -> None:
    """Check that ``distribution`` and the installed ``cerberus-core`` are both this release.

    Raises:
        ReleaseMismatchError: naming both versions and the fix.
    """
    found = {name: installed_version(name) for name in ("cerberus-core", distribution)}
    wrong = {name: v for name, v in found.items() if v != VERSION}
    if wrong:
        what = ", ".join(f"{name} {v or '(not installed)'}" for name, v in wrong.items())
        raise ReleaseMismatchError(f"{distribution} needs the Cerberus toolkit's cerberus-core {VERSION}, found {what}; "
                                   f"{INSTALL_HINT}")
