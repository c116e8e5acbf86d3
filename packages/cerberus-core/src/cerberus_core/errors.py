"""Typed errors of the toolkit: the CLI reports any :class:`CerberusError` as one line, exit 2."""
from __future__ import annotations


class CerberusError(Exception):
    """Base of the toolkit's errors about user input (the message names the problem and the fix)."""


class DatasetError(CerberusError, ValueError):
    """A dataset folder, manifest or shard is missing, invalid or damaged."""


class ConfigError(CerberusError, ValueError):
    """A configuration value, preset or option is invalid."""
