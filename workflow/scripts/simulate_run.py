"""Adapter: simulate one run (pose_uncertainty.sweep.simulate)."""

import sys

sys.stderr = open(snakemake.log[0], "w", encoding="utf-8")  # noqa: F821

from pose_uncertainty.sweep import simulate  # noqa: E402

simulate(
    snakemake.params.config,  # noqa: F821
    snakemake.output.log,  # noqa: F821
    snakemake.output.timings,  # noqa: F821
)
