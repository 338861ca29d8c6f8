"""Adapter: draw a set-level figure (pose_uncertainty.pipeline_figures.render_set_figure)."""

import sys

sys.stderr = open(snakemake.log[0], "w", encoding="utf-8")  # noqa: F821

from pose_uncertainty.pipeline_figures import render_set_figure  # noqa: E402

render_set_figure(
    snakemake.params.kind,  # noqa: F821
    list(snakemake.input.logs),  # noqa: F821
    snakemake.output[0],  # noqa: F821
    snakemake.params.title,  # noqa: F821
)
