"""Adapter: simulate one localization run (pose_uncertainty.logs.localization_log.simulate_localization)."""

from contextlib import redirect_stderr

from pose_uncertainty.logs.localization_log import simulate_localization

sm = snakemake  # noqa: F821 - injected by Snakemake
with open(sm.log[0], "w", encoding="utf-8") as log, redirect_stderr(log):
    simulate_localization(dict(sm.params.config), sm.output.log, sm.output.timings)
