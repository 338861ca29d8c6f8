"""The pipeline's own configuration keys (how runs become jobs, how the report shows a sweep).

One definition each, as the run keys (:class:`~pose_uncertainty.experiments.config_keys.Key`):
:mod:`pose_uncertainty.experiments.schema` writes them into ``workflow/schemas/config.schema.yaml``
(top-level :data:`PIPELINE_KEYS`, the ``report`` section's :data:`REPORT_KEYS`), whose defaults the
validated configuration then holds.
"""

from __future__ import annotations

from .config_keys import Key

__all__ = ["PIPELINE_KEYS", "REPORT_KEYS"]

#: Top-level keys of the pipeline configuration.
PIPELINE_KEYS: tuple[Key, ...] = (
    Key("runs_per_job", "integer", "1",
        "The most runs (dead-reckoning or localization) one pipeline job executes, in one process (a chunk "
        "of a set's runs, in order). 1: one job per run, each log its own target. Above 1 the runs of a set "
        "are cut into chunks, one job each (one cluster job each on SLURM); every log is byte-identical to "
        "the one its own job writes, the chunk's runs' timings go to one file per chunk, and a changed run "
        "reruns only its chunk.",
        default=1, lo=1, hi=10_000),
)  # fmt: skip

#: Keys of the ``report`` section.
REPORT_KEYS: tuple[Key, ...] = (
    Key("summary_above", "integer", "1",
        "A set of more runs than this shows summary views drawn from its table (heat maps of each "
        "measure over two swept axes, partial-dependence lines, sensitivity indices) instead of "
        "per-run figures, and links its table as a CSV file instead of printing every row.",
        default=50, lo=1, hi=1_000_000),
)  # fmt: skip
