"""Adapter: one CSV of per-run measures for a set (pose_uncertainty.report.collect_table)."""

import sys

sys.stderr = open(snakemake.log[0], "w", encoding="utf-8")  # noqa: F821

from pose_uncertainty.report import collect_table  # noqa: E402

collect_table(
    snakemake.wildcards.set,  # noqa: F821
    list(snakemake.input.logs),  # noqa: F821
    list(snakemake.input.timings),  # noqa: F821
    snakemake.output[0],  # noqa: F821
)
