"""The toolkit's typed errors: what a user can fix. The ``cerberus`` command turns each into one line
on standard error and exit status 2 (:mod:`cerberus_core.cli`); anything else is a bug."""
from __future__ import annotations


class CerberusError(Exception):
    """Base class of errors whose message names the problem and the fix."""


class DatasetError(CerberusError, ValueError):
    """A dataset folder is missing, incomplete or corrupt."""


class ConfigError(CerberusError, ValueError):
    """A configuration value or command-line argument is invalid."""
