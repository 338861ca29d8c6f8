"""Adapter: one CSV of logged measures for a set (pose_uncertainty.pipeline.tables.collect_table)."""

from contextlib import redirect_stderr

from pose_uncertainty.pipeline.tables import collect_table

sm = snakemake  # noqa: F821 - injected by Snakemake
with open(sm.log[0], "w", encoding="utf-8") as log, redirect_stderr(log):
    collect_table(sm.wildcards.set, list(sm.params.logs), list(sm.params.timings), sm.output[0])
