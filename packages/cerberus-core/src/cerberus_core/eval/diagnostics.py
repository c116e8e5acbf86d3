"""The table of evaluation diagnostics: one row per diagnostic, the one list ``cerberus eval`` is made from.

Beside the standard voxel IoU (always scored: the paper's Table 1), :func:`~cerberus_core.eval.runner.evaluate_dataset`
runs every row of :data:`DIAGNOSTICS` that :attr:`EvalConfig.skip <cerberus_core.eval.runner.EvalConfig>` does not
name, in table order but those marked :attr:`Diagnostic.first` first (each image's record gets their fields in
that order). From the row come:

* the switch: its :attr:`Diagnostic.name` in ``EvalConfig(skip=(...))``, which ``cerberus eval`` offers as a flag
  of its own (``cerberus_core.cli.eval``), with :attr:`Diagnostic.about` as the flag's help;
* the accumulator: :attr:`Diagnostic.accumulator`, a class following
  :class:`~cerberus_core.eval.accumulators.MetricAccumulator` (made by ``for_evaluation(context)``, fed every
  batch, then ``summary()``);
* what it needs (:data:`NEEDS`): a renderer is made once when a row that runs needs one; scipy is checked
  before anything runs;
* its entries of :class:`~cerberus_core.eval.runner.EvaluationResult` and ``results.json``: ``{key: summary}``
  (``None`` when skipped), or what :attr:`Diagnostic.outputs` makes of the accumulator;
* its section of ``results.md`` (:attr:`Diagnostic.section`, from the whole result's JSON form) and its line of
  the summary ``cerberus eval`` prints (:attr:`Diagnostic.line`, from its own summary).

A new diagnostic is one module (its accumulator, line and section) and one row here (docs/architecture.md,
"Adding an evaluation diagnostic").
"""
from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from importlib.util import find_spec
from typing import Any

from cerberus_core.errors import ConfigError, MissingPackageError, UnknownPluginError
from cerberus_core.eval.accumulators import MetricAccumulator
from cerberus_core.eval.allocation import Allocation, allocation_line, allocation_section
from cerberus_core.eval.depth import DepthAccumulator, depth_line, depth_section
from cerberus_core.eval.hard import HardHumanIoU
from cerberus_core.eval.part_quality import PartQuality, part_quality_section
from cerberus_core.eval.segments import BodySegments, segments_line, segments_section
from cerberus_core.eval.standard import SCORER_ENTRY_POINT
from cerberus_core.eval.visibility import PartVisibility, visibility_line, visibility_section
from cerberus_core.plugins import get_metric
from cerberus_core.plumbing.names import did_you_mean

#: What a diagnostic can need, and what the evaluation does about it.
NEEDS: dict[str, str] = {
    "renderer": "renders in the input views (one backend, made once for every diagnostic that needs one)",
    "scipy": "scipy's k-d trees (checked before anything runs: pip install 'cerberus-core[eval]')",
    "segments": "ground-truth per-vertex segment labels (reported as missing when the data has none)",
    "poses": "several views of each test pose (reported as not measured, and why, when no pose has two)",
    "canonical": "a canonical-pose image of each subject (not reported without one)",
}


@dataclass(frozen=True)
class Diagnostic:
    """One row of :data:`DIAGNOSTICS`.

    Attributes:
        name: the switch (``EvalConfig(skip=(name,))``, a flag of ``cerberus eval``) and, unless ``key`` says
            otherwise, the ``results.json`` key of its summary.
        accumulator: its accumulator class (:class:`~cerberus_core.eval.accumulators.MetricAccumulator`).
        about: what it measures, one phrase (the flag's help is "skip " and this).
        needs: keys of :data:`NEEDS`.
        key: the ``results.json`` key of its summary (default ``name``).
        line: its one line of the printed summary, from its summary's JSON form (``None``: no line).
        section: its ``results.md`` section, from the whole result's JSON form (``None``: no section).
        outputs: its ``results.json`` entries from its accumulator (``None`` when skipped); default
            ``{key: accumulator.summary()}``.
        first: it runs before the rows not so marked, so its fields come first in each image's record (right
            after the standard IoU's); its entries, section and line keep its place in the table. Part
            visibility's ``visible_pixels`` is so placed, as in every ``results.json`` since it was added.

    Example: a row is looked up by its name; part visibility writes its summary under a key of its own and
    runs first:

        >>> row = next(d for d in DIAGNOSTICS if d.name == "visibility")
        >>> row.accumulator.__name__, row.key, sorted(row.needs), row.first
        ('PartVisibility', 'part_visibility', ['renderer'], True)
        >>> row.results(None)  # skipped: its entry is None
        {'part_visibility': None}
    """

    name: str
    accumulator: type[MetricAccumulator]
    about: str
    needs: frozenset[str] = frozenset()
    key: str = ""
    line: Callable[[Any], str] | None = None
    section: Callable[[Mapping[str, Any]], list[str]] | None = None
    outputs: Callable[[Any], dict[str, Any]] | None = None
    first: bool = False

    def __post_init__(self) -> None:
        if not self.key:
            object.__setattr__(self, "key", self.name)
        unknown = set(self.needs) - set(NEEDS)
        if unknown:
            raise ConfigError.about("needs", sorted(unknown), f"diagnostic {self.name!r}: not one of {sorted(NEEDS)}")

    def results(self, accumulator: MetricAccumulator | None) -> dict[str, Any]:
        """Its entries of a result (``accumulator``: ``None`` when it was skipped)."""
        if self.outputs is not None:
            return self.outputs(accumulator)
        return {self.key: None if accumulator is None else accumulator.summary()}


DIAGNOSTICS: list[Diagnostic] = [
    Diagnostic("hard", HardHumanIoU, "the Hard Human test (each subject's canonical part shapes posed by its other "
               "images)", frozenset({"canonical"}), outputs=HardHumanIoU.outputs),
    Diagnostic("part_quality", PartQuality, "part quality against the ground-truth semantic parts (the slowest "
               "diagnostic)", frozenset({"scipy", "segments"}), section=part_quality_section),
    Diagnostic("visibility", PartVisibility, "how often each learned part is wholly hidden in its input view",
               frozenset({"renderer"}), key="part_visibility", line=visibility_line, section=visibility_section,
               first=True),
    Diagnostic("depth", DepthAccumulator, "depth across the views of each test pose (translation disagreement, "
               "turned-view silhouette IoU)", frozenset({"renderer", "poses"}),
               line=lambda depth: "depth: " + depth_line(depth), section=depth_section),
    Diagnostic("segments", BodySegments, "the body segments (recall, off-body voxels and input-view coverage per "
               "ground-truth segment; the IoU lost when each learned part is deleted)",
               frozenset({"renderer", "scipy", "segments"}), line=segments_line, section=segments_section),
    Diagnostic("allocation", Allocation, "the allocation diagnostics (per learned part its keypoint's spread around "
               "the silhouette centroid and the foreground it alone covers; per segment the nearest keypoint)",
               frozenset({"renderer"}), line=allocation_line, section=allocation_section),
]
"""Every evaluation diagnostic, in the order they report (see the module docstring); they run in this order too,
the rows marked :attr:`Diagnostic.first` before the others."""


def diagnostic_names() -> list[str]:
    """The switches of :data:`DIAGNOSTICS`, in order.

    Example:
        >>> diagnostic_names()
        ['hard', 'part_quality', 'visibility', 'depth', 'segments', 'allocation']
    """
    return [d.name for d in DIAGNOSTICS]


def check_skip(skip: Sequence[str]) -> tuple[str, ...]:
    """``skip`` as a tuple of diagnostic names, every one a row of :data:`DIAGNOSTICS`, else a
    :class:`ConfigError` naming it (with "did you mean").

    Example:
        >>> check_skip(["depth", "hard"])
        ('depth', 'hard')
        >>> check_skip(["deph"])
        Traceback (most recent call last):
        ...
        cerberus_core.errors.ConfigError: skip = 'deph': is not a diagnostic (did you mean 'depth'?); ...
    """
    if isinstance(skip, str):
        raise ConfigError.about("skip", skip, "must be a sequence of diagnostic names, not one string",
                                f"`skip=({skip!r},)`")
    names = diagnostic_names()
    for name in skip:
        if name not in names:
            raise ConfigError.about("skip", name, "is not a diagnostic" + did_you_mean(str(name), names)
                                    + f"; the diagnostics: {', '.join(names)}")
    return tuple(skip)


def running(skip: Sequence[str]) -> list[Diagnostic]:
    """The rows that run when ``skip`` names the others, in the order they run: those marked
    :attr:`Diagnostic.first`, then the others, each in table order.

    Example:
        >>> [d.name for d in running(skip=("hard", "segments"))]  # visibility is marked first
        ['visibility', 'part_quality', 'depth', 'allocation']
    """
    return sorted((d for d in DIAGNOSTICS if d.name not in skip), key=lambda d: not d.first)


def needed(skip: Sequence[str], need: str) -> bool:
    """Whether a row that runs needs ``need`` (a key of :data:`NEEDS`).

    Example: every row that needs a renderer skipped, then all but one:

        >>> needed(("visibility", "depth", "segments", "allocation"), "renderer")
        False
        >>> needed(("visibility", "depth", "segments"), "renderer")  # allocation renders
        True
    """
    return any(need in d.needs for d in running(skip))


def check_eval_packages(skip: Sequence[str] = (), metric: bool = True) -> None:
    """Before an evaluation starts: every optional package it needs is installed (cerberus-metrics, through its
    metric entry point, unless ``metric`` is false: the caller brings its own scorer; scipy, for the rows that need
    it and ``skip`` does not name), else one :class:`MissingPackageError` naming them all and the extra that brings
    them, ``cerberus-core[eval]``."""
    missing = []
    if metric:
        try:
            get_metric(SCORER_ENTRY_POINT)
        except UnknownPluginError:
            missing.append("cerberus-metrics")
    if needed(skip, "scipy") and find_spec("scipy") is None:
        missing.append("scipy")
    if missing:
        many = len(missing) > 1
        raise MissingPackageError(f"evaluation needs {' and '.join(missing)}, which {'are' if many else 'is'} not "
                                  f"installed: pip install 'cerberus-core[eval]' brings {'them' if many else 'it'} "
                                  "(from the toolkit's wheelhouse: README, 'Installing with pip')")
