"""The toolkit's typed errors: one base class, so a caller (the ``cerberus`` command) can report any
of them the same way, and one module, so that no layer imports another just for an exception.

* :class:`CerberusError` — base of every error the toolkit raises on purpose (its message names
  the file or key at fault and the fix);
* :class:`DatasetError` — a dataset folder or mesh folder is missing, corrupt, incomplete or of
  another format;
* :class:`ConfigError` — a configuration (YAML preset, config file, ``--set``) is invalid;
* :class:`ShapeError`, :class:`DeviceError` — tensors of the wrong shape or dtype, or on different
  devices (the render ops and every ``check_shapes`` call);
* :class:`MissingPackageError` — an optional package a feature needs is not installed (the message
  names the ``pip install`` that brings it);
* :class:`OutputError` — a result cannot be written (read-only, unwritable or full destination, a name
  the file system refuses); nothing half-written is left behind.

Errors that belong to one module derive from :class:`CerberusError` there (the plugin errors in
:mod:`cerberus_core.plugins`, the lock, checkpoint, zoo and image-input errors).

``DatasetError`` and ``ConfigError`` are also ``ValueError``\\ s, so ``except ValueError`` keeps
catching them; ``OutputError`` is an ``OSError`` (with the original ``errno``).
"""
from __future__ import annotations


class CerberusError(Exception):
    """Base class of the toolkit's own errors."""


class DatasetError(CerberusError, ValueError):
    """A dataset folder (or a folder of meshes) is missing, corrupt, incomplete or of another format;
    the message names the file and the fix."""


class ConfigError(CerberusError, ValueError):
    """An invalid configuration: the message names the key, the value and what is allowed.

    A setting checked by :mod:`cerberus_core.fields` also carries ``key`` (the dotted key or field
    name), ``value`` and ``problem`` (what is allowed), so that a front end can say it in its own terms
    (the ``cerberus`` command names its flag); they are ``None`` otherwise.
    """

    def __init__(self, message: str, *, key: str | None = None, value: object = None, problem: str | None = None):
        super().__init__(message)
        self.key, self.value, self.problem = key, value, problem


class MissingPackageError(CerberusError, ImportError):
    """An optional package is not installed: the message names what needs it and the ``pip install`` that
    brings it (an ``ImportError`` too, for callers that catch one)."""


class ShapeError(CerberusError, ValueError):
    """A tensor of the wrong shape or dtype (:func:`cerberus_core.shapes.check_shapes`): the message names
    the function, every tensor's expected and actual shape, and the sizes the others bound."""


class DeviceError(CerberusError, ValueError):
    """Tensors that must be on one device are not: the message names each tensor's device."""


class OutputError(CerberusError, OSError):
    """A file or folder of results cannot be written: the message names the path, the reason (permission,
    read-only or full file system, a name too long) and the fix."""


__all__ = ["CerberusError", "ConfigError", "DatasetError", "DeviceError", "MissingPackageError", "OutputError", "ShapeError"]
