"""Adapter: draw a study's figure from its log, by the study's kind (pose_uncertainty.present.pipeline_figures)."""

from contextlib import redirect_stderr

from pose_uncertainty.present.pipeline_figures import render_study_figure

sm = snakemake  # noqa: F821 - injected by Snakemake
with open(sm.log[0], "w", encoding="utf-8") as log, redirect_stderr(log):
    render_study_figure(sm.input.log, sm.output[0])
