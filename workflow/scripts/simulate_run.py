"""Adapter: simulate one run (pose_uncertainty.logs.sweep.simulate); stderr goes to the rule's log."""

from contextlib import redirect_stderr

from pose_uncertainty.logs.sweep import simulate

sm = snakemake  # noqa: F821 - injected by Snakemake
with open(sm.log[0], "w", encoding="utf-8") as log, redirect_stderr(log):
    simulate(sm.params.config, sm.output.log, sm.output.timings)
