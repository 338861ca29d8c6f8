"""What the result of every kind of run holds beside its own data.

:class:`Measured` is the base of :class:`~pose_uncertainty.experiments.run.RunResult` (a
dead-reckoning run) and :class:`~pose_uncertainty.experiments.localization.LocalizationResult`
(a localization run): every measure computed where the run executes, with its unit and its
definition (:mod:`pose_uncertainty.analysis.measures`), the wall-clock timings and the
provenance. Its fields are keyword-only, so each kind keeps its own fields first.
"""

from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["Measured"]


@dataclass(frozen=True, eq=False, kw_only=True)
class Measured:
    """The measures, timings and provenance of a run (keyword-only fields).

    Attributes
    ----------
    metrics : dict of str to float — every measure of the run, deterministic
    metric_units : dict of str to str — the unit of each measure
    metric_definitions : dict of str to str — the definition of each measure
    timings : dict of str to float — wall-clock durations [s]; NOT deterministic
    provenance : dict of str to str — package version, environment.lock sha256, git commit, the
        machine's arithmetic (:func:`pose_uncertainty.core.provenance.provenance`)
    """

    metrics: dict[str, float] = field(default_factory=dict)
    metric_units: dict[str, str] = field(default_factory=dict)
    metric_definitions: dict[str, str] = field(default_factory=dict)
    timings: dict[str, float] = field(default_factory=dict)
    provenance: dict[str, str] = field(default_factory=dict)
