"""Adapter: draw figures of one run log (pose_uncertainty.present.pipeline_figures.render_run_figures)."""

from contextlib import redirect_stderr

from pose_uncertainty.present.pipeline_figures import render_run_figures

sm = snakemake  # noqa: F821 - injected by Snakemake
kinds = sm.params.kinds
with open(sm.log[0], "w", encoding="utf-8") as log, redirect_stderr(log):
    render_run_figures(sm.input.log, [kinds] if isinstance(kinds, str) else list(kinds), list(sm.output))
