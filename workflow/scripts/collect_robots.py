"""Adapter: the robots' calibration outputs → reports/tables/robots/robots.csv (pose_uncertainty.pipeline.robots)."""

from contextlib import redirect_stderr

from pose_uncertainty.pipeline.robots import collect_robot_table

sm = snakemake  # noqa: F821 - injected by Snakemake
with open(sm.log[0], "w", encoding="utf-8") as log, redirect_stderr(log):
    collect_robot_table(list(sm.params.names), list(sm.params.dirs), sm.output[0])
