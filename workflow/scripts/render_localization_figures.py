"""Adapter: draw the figures of one localization log (pose_uncertainty.present.localization_figures)."""

from contextlib import redirect_stderr

from pose_uncertainty.present.localization_figures import render_localization_run_figures

sm = snakemake  # noqa: F821 - injected by Snakemake
with open(sm.log[0], "w", encoding="utf-8") as log, redirect_stderr(log):
    render_localization_run_figures(sm.input.log, list(sm.params.kinds), [getattr(sm.output, k) for k in sm.params.kinds])
