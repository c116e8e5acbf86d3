"""How the ``cerberus`` command says the settings the library names: :class:`FlagNames`, each sub-command's table
of its flags (passed with ``set_defaults(flag_names=...)``), used by the error boundary and the warning format of
:mod:`cerberus_core.cli`. The library says a setting in Python terms (docs/architecture.md, "Errors"); this is the
one place that says it as the flag of the command that was run, or as ``--set KEY=VALUE``."""
from __future__ import annotations

import dataclasses
import re
import shlex
from collections.abc import Mapping

#: A setting a library message names: `name` or `name=value` in backticks (a parameter, a field, a config key).
SETTING = re.compile(r"`([a-z_][a-z0-9_]*(?:\.[a-z0-9_]+)*)(?:=([^`]*))?`")


@dataclasses.dataclass(frozen=True)
class FlagNames:
    """How one command says the settings the library names (a sub-command passes its own with
    ``set_defaults(flag_names=...)``; :func:`main` adds the flags typed).

    Attributes:
        flags: setting (a library parameter, a settings field or a config key) → this command's flag,
            e.g. ``{"run_dir": "--out", "resume": "--resume"}``.
        config: the settings class whose keys ``--set KEY=VALUE`` sets (``None``: the command has no ``--set``).
        typed: the flags on this command line: a config key that has a flag of its own is said with that flag
            where it was typed, else with ``--set``.
    """

    flags: Mapping[str, str] = dataclasses.field(default_factory=dict)
    config: type | None = None
    typed: frozenset[str] = frozenset()

    def is_config_key(self, key: str) -> bool:
        """Whether ``--set`` sets ``key`` on this command (its first part is a field of :attr:`config`)."""
        return self.config is not None and key.split(".")[0] in {f.name for f in dataclasses.fields(self.config)}

    def flag(self, key: str) -> str | None:
        """The flag that says ``key`` here, or ``None`` (a config key set with ``--set``, or not a setting here)."""
        flag = self.flags.get(key)
        return flag if flag and (flag in self.typed or not self.is_config_key(key)) else None

    def text(self, text: str) -> str:
        """``text`` with each setting in backticks said as this command's flag (`` `data=DATASET` `` → ``--data
        DATASET``; a switch: `` `resume=True` `` → ``--resume``, `` `resume=False` `` → ``without --resume``) or
        ``--set`` (`` `train.steps=VALUE` `` → ``--set train.steps=VALUE``); a setting this command does not take
        stays as it is."""
        def say(match: re.Match) -> str:
            key, value = match[1], match[2]
            if flag := self.flag(key):
                return {None: flag, "True": flag, "False": f"without {flag}"}.get(value, f"{flag} {value}")
            if self.is_config_key(key):
                return key if value is None else f"--set {key}={value}"
            return match[0]

        return SETTING.sub(say, text)

    def error(self, exc: BaseException) -> str:
        """The message of ``exc`` in this command's flags: an error about one setting (``key``, ``value``,
        ``problem``) leads with its flag (``--resolution 999: must be ...``) or, for a config key, ends with
        the ``--set`` that fixes it; every setting the message names is said as a flag (:meth:`text`)."""
        key, problem = getattr(exc, "key", None), getattr(exc, "problem", None)
        if key is None or problem is None:
            return self.text(str(exc))
        said, flag, value = self.text(problem), self.flag(key), getattr(exc, "value", None)
        if flag:
            shown = "" if value is None or isinstance(value, bool) else f" {shlex.quote(str(value))}"
            return f"{flag}{shown}: {said}"
        if self.is_config_key(key):
            return f"{key} = {value!r}: {said}" + ("" if f"--set {key}=" in said else f" (--set {key}=VALUE)")
        return self.text(str(exc))


def typed_flags(argv: list[str]) -> frozenset[str]:
    """The flags on a command line (``--out``, ``--set``; ``--out=DIR`` counts as ``--out``)."""
    return frozenset(a.partition("=")[0] for a in argv if a.startswith("--"))
