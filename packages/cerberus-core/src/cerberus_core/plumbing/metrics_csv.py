"""A run's ``metrics.csv`` read without torch: its rows (:func:`read_rows`) and how long the run trained
(:func:`training_time`). :class:`cerberus_core.train.logs.MetricsLog` writes the file; the training logs, the
comparison tables (:mod:`cerberus_core.eval.compare`) and the experiments read it through here."""
from __future__ import annotations

import csv
from pathlib import Path
from typing import NamedTuple

#: The file of a run folder that :class:`cerberus_core.train.logs.MetricsLog` writes: one row per logged step.
METRICS_CSV = "metrics.csv"


def read_rows(path: str | Path) -> list[dict[str, str]]:
    """The rows of a ``metrics.csv`` as ``{column: text}`` (an empty cell: ``""``), in the file's order; ``[]``
    when there is no such file.

    Example:
        >>> import tempfile
        >>> csv_path = Path(tempfile.mkdtemp()) / METRICS_CSV
        >>> _ = csv_path.write_text("step,elapsed_s\\n20,4.5\\n40,\\n")
        >>> read_rows(csv_path), read_rows(csv_path.parent / "missing.csv")
        ([{'step': '20', 'elapsed_s': '4.5'}, {'step': '40', 'elapsed_s': ''}], [])
    """
    path = Path(path)
    if not path.is_file():
        return []
    with path.open(newline="") as f:
        return list(csv.DictReader(f))


class TrainingTime(NamedTuple):
    """A run's training length from its ``metrics.csv`` (:func:`training_time`)."""

    steps: int
    """The ``step`` of the last row with an ``elapsed_s``."""
    seconds: float
    """Wall-clock training time in seconds, summed over the sittings."""


def training_time(csv_path: str | Path) -> TrainingTime | None:
    """The steps and the wall-clock training seconds of a run's ``metrics.csv``; ``None`` when the file is
    missing or no row has an ``elapsed_s``.

    ``elapsed_s`` (seconds) restarts at every sitting: the clock starts when ``cerberus train`` starts, and again
    at each resume. A sitting ends where ``elapsed_s`` drops, and ``seconds`` is the sum over the sittings
    of each sitting's last ``elapsed_s``, so the last row's ``elapsed_s`` alone undercounts a resumed run. Not
    counted: the seconds of the rows that a resume dropped (an interrupted sitting's steps after its last
    checkpoint, which the next sitting trains and times again), and a sitting's time after its last logged row.
    Steps per second is ``steps / seconds``.

    Example:
        >>> import tempfile
        >>> csv_path = Path(tempfile.mkdtemp()) / METRICS_CSV
        >>> _ = csv_path.write_text("step,elapsed_s\\n20,5.0\\n40,10.0\\n60,4.0\\n80,9.0\\n100,\\n")  # resumed at 40
        >>> training_time(csv_path)
        TrainingTime(steps=80, seconds=19.0)
        >>> print(training_time(csv_path.parent / "missing.csv"))
        None
    """
    rows = [r for r in read_rows(csv_path) if r.get("elapsed_s") not in (None, "")]
    if not rows:
        return None
    seconds, previous = 0.0, 0.0
    for r in rows:
        elapsed = float(r["elapsed_s"])
        if elapsed < previous:  # a new sitting: the previous one ended at its last row
            seconds += previous
        previous = elapsed
    return TrainingTime(int(rows[-1]["step"]), seconds + previous)
