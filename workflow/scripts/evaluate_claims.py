"""Adapter: evaluate the claims of the theses (pose_uncertainty.pipeline.claims.write_claims)."""

from contextlib import redirect_stderr

from pose_uncertainty.pipeline.claims import write_claims

sm = snakemake  # noqa: F821 - injected by Snakemake
with open(sm.log[0], "w", encoding="utf-8") as log, redirect_stderr(log):
    tables = dict(zip(sm.params.sets, sm.input.tables, strict=True))
    tables |= dict(zip(sm.params.loc_sets, sm.input.loc_tables, strict=True))  # localization/<set>
    write_claims(tables, sm.output[0])
