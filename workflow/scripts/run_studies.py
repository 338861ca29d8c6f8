"""Adapter: seed 001's studies as JSON (pose_uncertainty.present.report.run_studies)."""

from contextlib import redirect_stderr

from pose_uncertainty.present.report import run_studies

sm = snakemake  # noqa: F821 - injected by Snakemake
with open(sm.log[0], "w", encoding="utf-8") as log, redirect_stderr(log):
    run_studies(sm.output[0], quick=bool(sm.params.quick))
