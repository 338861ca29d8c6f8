"""Adapter: evaluate the claims of SPEC §5 (pose_uncertainty.analysis.claims.write_claims)."""

from contextlib import redirect_stderr

from pose_uncertainty.analysis.claims import write_claims

sm = snakemake  # noqa: F821 - injected by Snakemake
with open(sm.log[0], "w", encoding="utf-8") as log, redirect_stderr(log):
    write_claims(dict(zip(sm.params.sets, sm.input.tables, strict=True)), sm.output[0])
