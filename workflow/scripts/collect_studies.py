"""Adapter: the study logs → reports/studies.json (pose_uncertainty.experiments.study.collect_studies)."""

from contextlib import redirect_stderr

from pose_uncertainty.experiments.study import collect_studies

sm = snakemake  # noqa: F821 - injected by Snakemake
with open(sm.log[0], "w", encoding="utf-8") as log, redirect_stderr(log):
    collect_studies(list(sm.input.logs), sm.output[0])
