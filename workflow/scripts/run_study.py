"""Adapter: run one configured study and write its log (pose_uncertainty.logs.study.run_study)."""

from contextlib import redirect_stderr

from pose_uncertainty.logs.study import run_study

sm = snakemake  # noqa: F821 - injected by Snakemake
with open(sm.log[0], "w", encoding="utf-8") as log, redirect_stderr(log):
    run_study(sm.wildcards.study, dict(sm.params.spec), sm.output[0])
