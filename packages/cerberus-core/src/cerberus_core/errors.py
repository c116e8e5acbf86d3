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

and the errors of one concept each: :class:`PluginError` (:class:`UnknownPluginError`,
:class:`DuplicatePluginError`, :class:`PluginLoadError`), :class:`ZooError`, :class:`IncompleteDatasetError`,
:class:`ManifestFormatError`, :class:`TrainingDatasetError`, :class:`NonFiniteError`, :class:`RunExistsError`,
:class:`NoCheckpointError`, :class:`NoEvaluationError`, :class:`IncomparableEvaluationsError`,
:class:`CheckpointError`, :class:`LockedError`, :class:`ImageInputError`, :class:`BodyError`,
:class:`ReleaseMismatchError` and :class:`UnknownSubjectError`.

Every error class of ``cerberus_core`` is defined here, and nowhere else (``tests/repo/test_raises.py``), so
that no module imports another just for an exception. The one exception class that is not an error is
:class:`cerberus_core.plumbing.signals.Terminated`, SIGTERM as a ``KeyboardInterrupt``.

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
from pathlib import Path


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

    Every one carries ``key`` (the dotted config key, parameter or field name: a front end says it in its own
    terms, the ``cerberus`` command as its flag or ``--set``) and ``value``; made with :meth:`about` (every check of
    :mod:`cerberus_core.fields`) it also carries ``problem`` (what is wrong or allowed, without the key), and its
    message is ``key = value: problem (fix)``. A message that does not read so passes ``key=`` itself (``problem``
    then ``None``); ``tests/repo/test_raises.py`` finds any made without a key.
    """

    def __init__(self, message: str, *, key: str, value: object = None, problem: str | None = None):
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
        ``splits.train.views``, in the message and its fix too); itself when it already names it so."""
        if not prefix or self.key.startswith(prefix):
            return self
        if self.problem is None:  # a message of its own: the key moves under the section, the words stay
            return type(self)(str(self), key=prefix + self.key, value=self.value)
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



# ------------------------------------------------------------------ the errors of one concept each
class PluginError(CerberusError, RuntimeError):
    """Base class of plugin discovery errors (:mod:`cerberus_core.plugins`): a :class:`CerberusError` (the
    ``cerberus`` command reports it in one line like the others), still a ``RuntimeError`` for callers
    that caught it as one."""


class UnknownPluginError(PluginError, KeyError):
    """No plugin of that name is installed."""

    def __str__(self) -> str:  # KeyError would repr() the message
        return str(self.args[0])


class DuplicatePluginError(PluginError):
    """Two installed distributions register the same plugin name."""


class PluginLoadError(PluginError):
    """A plugin is registered but importing it failed."""


class ZooError(CerberusError, ValueError):
    """A pretrained model is unknown, missing or fails its checksum."""


class IncompleteDatasetError(DatasetError):
    """A split whose generation has not finished. ``root`` is the dataset folder and ``problem`` the message
    without its fix, so that a front end can name its own way to finish it (the ``cerberus`` command: the
    ``cerberus data generate`` command that resumes it)."""

    def __init__(self, root: Path, problem: str) -> None:
        self.root, self.problem = Path(root), problem
        super().__init__(f"{problem}; finish generating it (it resumes) with `Dataset.open(root).resume()` "
                         "(cerberus_core.datasets.dataset)")


class TrainingDatasetError(DatasetError, TypeError):
    """An object given as the training dataset breaks the contract of :mod:`cerberus_core.train.data` (a missing attribute, a ``scene`` that
    is not a :class:`SceneSetup`, no quadruplets); a ``TypeError`` (and a ``ValueError``) too, for callers that
    caught one."""


class NonFiniteError(CerberusError, RuntimeError):
    """The loss or gradient became NaN or infinite and the run was stopped (``cerberus train``: exit 3)."""

    exit_code = 3


class RunExistsError(CerberusError, FileExistsError):
    """A fresh training was pointed at a folder that already holds files."""


class NoCheckpointError(CerberusError, FileNotFoundError):
    """``resume=True`` but the run folder has no checkpoint."""


class NoEvaluationError(CerberusError, FileNotFoundError):
    """A path that holds no evaluation: neither a ``results.json`` nor a folder with one (an evaluation's own, or a
    run's ``eval/``); the message names the path and how to make one (:mod:`cerberus_core.eval.compare`)."""


class IncomparableEvaluationsError(DatasetError):
    """Evaluations measured under different settings (:data:`cerberus_core.eval.compare.MEASUREMENT`: protocol,
    resolution, ground-truth open-mesh policy, the data scored), whose per-image values cannot be paired: the
    message names each setting that differs with each evaluation's value, and the fix. ``differences`` is
    ``{setting: {evaluation name: value}}`` of those settings."""

    def __init__(self, message: str, *, differences: dict[str, dict[str, object]]) -> None:
        super().__init__(message)
        self.differences = differences


class CheckpointError(CerberusError, ValueError):
    """A model file or run folder cannot be loaded; the message names the file and what to pass instead."""


class LockedError(CerberusError):
    """Another live process holds the folder's lock."""


class ImageInputError(CerberusError, ValueError):
    """An input image cannot be used; the message names the file and what to do."""


class BodyError(CerberusError, ValueError):
    """A body source was asked for, or produced, what no dataset can hold: a count or pose id out of its
    range, a degenerate body, one outside the unit cube; the message names the subject, the pose and the fix
    (a ``ValueError`` too, for callers that caught one)."""


class ReleaseMismatchError(CerberusError, ImportError):
    """A toolkit distribution found a sibling of another release (or none installed) (:mod:`cerberus_core.release`;
    an ``ImportError`` too, as a backend raises it while it is imported)."""


class ManifestFormatError(DatasetError):
    """A record of a dataset's manifest that does not have the form of its type (a key missing or of another
    type); the reader that catches it names the manifest and the fix (:mod:`cerberus_core.datasets.manifest`)."""


class UnknownEntryError(CerberusError, KeyError):
    """A result read by a name it has no entry of (``result["hrad"]`` of
    :class:`cerberus_core.eval.runner.EvaluationResult`); a ``KeyError`` too, as a mapping's lookup raises."""

    def __str__(self) -> str:  # KeyError would repr() the message
        return str(self.args[0])


class UnknownSubjectError(CerberusError, KeyError):
    """The Hard Human test was asked to pose a subject it has no canonical image of
    (:meth:`cerberus_core.eval.hard.CanonicalParts.pose`); a ``KeyError`` too, as it was."""

    def __str__(self) -> str:  # KeyError would repr() the message
        return str(self.args[0])


__all__ = ["BackendError", "BodyError", "CerberusError", "CheckpointError", "ConfigError", "DatasetError",
           "DeviceError", "DuplicatePluginError", "ImageInputError", "IncomparableEvaluationsError",
           "IncompleteDatasetError", "InputTypeError", "LockedError", "ManifestFormatError", "MeshError",
           "MissingPackageError", "NoCheckpointError", "NoEvaluationError", "NonFiniteError", "OutputError",
           "PluginError", "PluginLoadError", "ReleaseMismatchError", "RenderInputError", "RunExistsError", "ShapeError",
           "TextFormatError", "TrainingDatasetError", "UnknownEntryError", "UnknownPluginError", "UnknownSubjectError",
           "ZooError", "shown"]
