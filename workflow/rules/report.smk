# The claims of SPEC §5 evaluated from the tables, and the self-contained HTML report.


rule evaluate_claims:
    input:
        tables=all_tables,
    output:
        "reports/claims.json",
    params:
        sets=SETS,
    log:
        "logs/evaluate_claims.log",
    benchmark:
        "data/benchmarks/evaluate_claims/all.tsv"
    script:
        "../scripts/evaluate_claims.py"


rule run_studies:
    output:
        "reports/studies.json",
    params:
        quick=lambda w: config["studies"]["quick"],
    log:
        "logs/run_studies.log",
    benchmark:
        "data/benchmarks/run_studies/all.tsv"
    script:
        "../scripts/run_studies.py"


rule build_report:
    input:
        tables=all_tables,
        claims=rules.evaluate_claims.output[0],
        figures=all_figures,
        benchmarks=all_benchmarks,
        template=REPORT_TEMPLATE,
        studies=studies_output,
        studies_figures=lambda w: list(studies_figures().values()),
        # the speed benchmarks' results, when `make bench` has written them (not made by the DAG)
        speed=lambda w: sorted(str(p) for p in Path("benchmarks/results").glob("*.json")),
    output:
        "reports/comparison.html",
    params:
        manifest=report_manifest(),
        sets=SETS,
        title=config["report"]["title"],
        studies_figures=studies_figures(),
    log:
        "logs/build_report.log",
    script:
        "../scripts/build_report.py"
