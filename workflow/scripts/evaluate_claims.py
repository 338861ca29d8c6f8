"""Adapter: evaluate the claims of the theses (pose_uncertainty.pipeline.claims.write_claims).

A set that is in the config but lacks the runs a claim reads fails the job with one line
(ClaimDataError: the claim, the set, the logged parameters it looked for), in the job's log
and on its standard error; no claims.json is written.
"""

from contextlib import redirect_stderr

from pose_uncertainty.pipeline.claims import ClaimDataError, write_claims

sm = snakemake  # noqa: F821 - injected by Snakemake
error = None
with open(sm.log[0], "w", encoding="utf-8") as log, redirect_stderr(log):
    tables = dict(zip(sm.params.sets, sm.input.tables, strict=True))
    tables |= dict(zip(sm.params.loc_sets, sm.input.loc_tables, strict=True))  # localization/<set>
    tables |= dict(zip(sm.params.robot_sets, sm.input.robot_tables, strict=True))  # robots
    try:
        studies = list(getattr(sm.input, "studies", []))  # reports/studies.json, when studies are configured
        write_claims(tables, sm.output[0], studies=studies[0] if studies else None)
    except ClaimDataError as exc:
        error = f"evaluate_claims: {exc}"
        print(error, file=log)
if error is not None:
    raise SystemExit(error)
