"""Adapter: a large sweep's summary from its table, and its figures from the summary
(pose_uncertainty.pipeline.sweep_summary.summarize_sweep, pose_uncertainty.present.pipeline_figures.render_sweep_figures)."""

from contextlib import redirect_stderr

from pose_uncertainty.pipeline.sweep_summary import summarize_sweep
from pose_uncertainty.present.pipeline_figures import render_sweep_figures

sm = snakemake  # noqa: F821 - injected by Snakemake
with open(sm.log[0], "w", encoding="utf-8") as log, redirect_stderr(log):
    summarize_sweep(sm.wildcards.set, sm.input.table, sm.output.summary)
    render_sweep_figures(sm.output.summary, {"sweep_heatmaps": sm.output.heatmaps, "sweep_dependence": sm.output.dependence})
