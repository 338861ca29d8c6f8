"""Adapter: draw a localization set's figure (pose_uncertainty.present.localization)."""

from contextlib import redirect_stderr

from pose_uncertainty.present.localization import render_localization_set_figure

sm = snakemake  # noqa: F821 - injected by Snakemake
with open(sm.log[0], "w", encoding="utf-8") as log, redirect_stderr(log):
    render_localization_set_figure(sm.wildcards.kind, list(sm.params.logs), list(sm.params.timings), sm.output[0],
                                   sm.params.title)
