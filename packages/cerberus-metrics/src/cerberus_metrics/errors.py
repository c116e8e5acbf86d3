"""The errors cerberus-metrics raises on purpose: one base, :class:`MetricsError`, so a caller catches them all
(the package stands alone, so this is not ``cerberus_core``'s ``CerberusError``); each message names the input,
the problem and the fix. :class:`~cerberus_metrics.io.MeshInputError` (an input mesh cannot be evaluated) is
one, with :class:`~cerberus_metrics.io.OpenMeshError` (a mesh that must be closed is not watertight) under it;
:class:`MeasurementError` another."""
from __future__ import annotations


class MetricsError(Exception):
    """Base class of cerberus-metrics' own errors."""


class MeasurementError(MetricsError, RuntimeError):
    """A measuring library returned what cannot be right (a count of samples that differs from the one asked
    for): a bug to report, with the numbers (a ``RuntimeError`` too, for callers that caught one)."""


__all__ = ["MeasurementError", "MetricsError"]
