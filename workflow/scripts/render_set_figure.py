"""Adapter: draw a set-level figure (pose_uncertainty.present.pipeline_figures.render_set_figure)."""

from contextlib import redirect_stderr

from pose_uncertainty.present.pipeline_figures import render_set_figure

sm = snakemake  # noqa: F821 - injected by Snakemake
with open(sm.log[0], "w", encoding="utf-8") as log, redirect_stderr(log):
    render_set_figure(sm.params.kind, list(sm.params.logs), sm.output[0], sm.params.title)
