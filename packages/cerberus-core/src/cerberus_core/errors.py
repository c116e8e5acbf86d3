"""The toolkit's typed errors: one base class, so a caller (the ``cerberus`` command) can report any
of them the same way, and one module, so that no layer imports another just for an exception.

* :class:`CerberusError` — base of every error the toolkit raises on purpose (its message names
  the file or key at fault and the fix);
* :class:`DatasetError` — a dataset folder or mesh folder is missing, corrupt, incomplete or of
  another format;
* :class:`ConfigError` — a setting (a config key from a YAML preset, a config file or overrides, a function's
  parameter, a settings object's field) is invalid;
* :class:`ShapeError`, :class:`DeviceError` — tensors of the wrong shape or dtype, or on different
  devices (the render ops and every ``check_shapes`` call);
* :class:`MissingPackageError` — an optional package a feature needs is not installed (the message
  names the ``pip install`` that brings it);
* :class:`OutputError` — a result cannot be written (read-only, unwritable or full destination, a name
  the file system refuses); nothing half-written is left behind;
* :class:`RenderInputError` — a camera or render call the renderer cannot draw (a field of view, image size
  or near/far out of range, more faces than a backend holds);
* :class:`MeshError` — a mesh (a template, a reconstruction's parts, an exported mesh) that is broken: no
  faces, faces indexing outside the vertices, templates that differ, NaN or inf vertices;
* :class:`BackendError` — a renderer backend cannot run here (its runtime does not start, no device of it
  matches the tensors');
* :class:`InputTypeError` — an argument of the wrong kind (not the model, renderer or reconstruction the function
  takes) or an option the callee does not know.

Errors that belong to one module derive from :class:`CerberusError` there (the plugin errors in
:mod:`cerberus_core.plugins`, the lock, checkpoint, zoo and image-input errors).

Each is also the builtin error it replaced, so ``except ValueError`` keeps catching them: ``DatasetError``,
``ConfigError``, ``ShapeError``, ``DeviceError``, ``RenderInputError`` and ``MeshError`` are ``ValueError``\\ s,
``BackendError`` a ``RuntimeError``, ``InputTypeError`` a ``TypeError``, ``OutputError`` an ``OSError`` (with
the original ``errno``).

Messages say the problem and the fix in Python terms, never a command-line flag: a setting is named as its
config key, parameter or field, in backticks where the fix sets it (`` `train.steps=VALUE` ``,
`` `resume=True` ``, `` `data` ``); the ``cerberus`` command says each in its own flags
(:mod:`cerberus_core.cli`; docs/architecture.md, "Errors").
"""
from __future__ import annotations

import os
import reprlib


class CerberusError(Exception):
    """Base class of the toolkit's own errors."""


class DatasetError(CerberusError, ValueError):
    """A dataset folder (or a folder of meshes) is missing, corrupt, incomplete or of another format;
    the message names the file and the fix."""


_REPR = reprlib.Repr()
_REPR.maxstring, _REPR.maxother, _REPR.maxlist, _REPR.maxtuple, _REPR.maxdict, _REPR.maxlevel = 60, 60, 6, 6, 4, 3

#: The most characters of a value a message echoes (:func:`shown`).
SHOWN_MAX = 100


def shown(value: object) -> str:
    """``value``'s repr for a message, bounded in work and length (:data:`SHOWN_MAX`): a setting given as a
    long text or a deep structure is named by its start, not echoed whole (issue 39: a 400-byte value with
    nested YAML aliases made a 17.5 MB error line)."""
    text = _REPR.repr(value)
    return text if len(text) <= SHOWN_MAX else text[:SHOWN_MAX - 3] + "..."


class ConfigError(CerberusError, ValueError):
    """An invalid setting: the message names the key, the value and what is allowed.

    An error about one setting (:meth:`about`; every check of :mod:`cerberus_core.fields`) also carries
    ``key`` (the dotted config key, parameter or field name), ``value`` and ``problem`` (what is wrong or
    allowed), so that a front end can say it in its own terms (the ``cerberus`` command names its flag);
    they are ``None`` otherwise.
    """

    def __init__(self, message: str, *, key: str | None = None, value: object = None, problem: str | None = None):
        super().__init__(message)
        self.key, self.value, self.problem = key, value, problem

    @classmethod
    def about(cls, key: str, value: object, problem: str, fix: str = "") -> ConfigError:
        """The error of the setting ``key``: ``key = value: problem (fix)`` (``key: problem`` when ``value``
        is ``None``; a path shown as it is written: the CLI escapes what a terminal must not receive), with
        ``key``, ``value`` and ``problem`` kept.

        Args:
            fix: the Python fix, where the problem does not say it, e.g. ``EvalSettings(resolution=...)``.
        """
        said = "" if value is None else f" = {os.fspath(value)}" if isinstance(value, os.PathLike) else f" = {shown(value)}"
        return cls(f"{key}{said}: {problem}" + (f" ({fix})" if fix else ""), key=key, value=value, problem=problem)

    def within(self, prefix: str) -> ConfigError:
        """This error with its key under the section ``prefix`` (``"splits.train."``: ``views`` becomes
        ``splits.train.views``, in the message and its fix too); itself when it names no key or already
        names it so."""
        if not prefix or self.key is None or self.key.startswith(prefix):
            return self
        message = prefix + str(self).replace(f"`{self.key}=", f"`{prefix}{self.key}=")
        return type(self)(message, key=prefix + self.key, value=self.value, problem=self.problem)


class MissingPackageError(CerberusError, ImportError):
    """An optional package is not installed: the message names what needs it and the ``pip install`` that
    brings it (an ``ImportError`` too, for callers that catch one)."""


class ShapeError(CerberusError, ValueError):
    """A tensor of the wrong shape or dtype (:func:`cerberus_core.shapes.check_shapes`), or with values outside
    its contract (NaN images): the message names the function, every tensor's expected and actual shape, and
    the sizes the others bound."""


class DeviceError(CerberusError, ValueError):
    """Tensors that must be on one device are not: the message names each tensor's device."""


class OutputError(CerberusError, OSError):
    """A file or folder of results cannot be written: the message names the path, the reason (permission,
    read-only or full file system, a name too long) and the fix."""


class RenderInputError(CerberusError, ValueError):
    """A camera or a render call the renderer cannot draw (field of view, image size, near/far planes, a
    backend's face limit): the message names the value and the range allowed."""


class MeshError(CerberusError, ValueError):
    """A broken mesh (a template without faces, faces outside the vertices, part sets on different templates,
    NaN or inf vertices): the message names the mesh and the fix."""


class BackendError(CerberusError, RuntimeError):
    """A renderer backend cannot run here (its runtime fails to start, it has no device matching the
    tensors'): the message names the backend, the cause and the fix."""


class TextFormatError(CerberusError, ValueError):
    """Text from outside (a manifest, a lock file, a weights file's metadata) that cannot be parsed: a number too
    long to read, nesting too deep; the message says what is wrong and the reader that caught it names the file."""


class InputTypeError(CerberusError, TypeError):
    """An argument of the wrong kind (an object that is not the model, renderer or reconstruction the function
    takes) or an option the callee does not know: the message names what came and what is taken."""


__all__ = ["BackendError", "CerberusError", "ConfigError", "DatasetError", "DeviceError", "InputTypeError",
           "MeshError", "MissingPackageError", "OutputError", "RenderInputError", "ShapeError",
           "TextFormatError", "shown"]
