"""Adapter: draw one figure of one run log (pose_uncertainty.pipeline_figures.render_run_figure)."""

import sys

sys.stderr = open(snakemake.log[0], "w", encoding="utf-8")  # noqa: F821

from pose_uncertainty.pipeline_figures import render_run_figure  # noqa: E402

render_run_figure(snakemake.input.log, snakemake.params.kind, snakemake.output[0])  # noqa: F821
