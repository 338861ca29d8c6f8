"""Adapter: evaluate the claims of SPEC §5 (pose_uncertainty.claims.write_claims)."""

import sys

sys.stderr = open(snakemake.log[0], "w", encoding="utf-8")  # noqa: F821

from pose_uncertainty.claims import write_claims  # noqa: E402

write_claims(
    dict(zip(snakemake.params.sets, snakemake.input.tables, strict=True)),  # noqa: F821
    snakemake.output[0],  # noqa: F821
)
