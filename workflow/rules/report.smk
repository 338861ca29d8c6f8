# The claims of the theses and the method guide from the tables, the pipeline's provenance from the
# logs, and the self-contained HTML report that formats them.


# the report's templates (they ship with the package, present/templates): hashed with its code, so editing one
# rebuilds the report and its companion pages
REPORT_TEMPLATES = (REPORT_TEMPLATE, ROBOTS_TEMPLATE, SWEEP_TEMPLATE, SKALKA_TEMPLATE, RUNS_TEMPLATE, FULL_TABLE_TEMPLATE, STYLE_SHEET)


rule evaluate_claims:
    input:
        tables=all_tables,
        loc_tables=localization_tables,
        # the studies' logged results: the claims of Skalka 2011's techniques read them
        studies=studies_json,
        robot_tables=robot_tables,
    output:
        "reports/claims.json",
    params:
        sets=SETS,
        loc_sets=localization_table_names(),
        robot_sets=["robots"] if ROBOTS else [],
        source=script_source("evaluate_claims"),
    log:
        "logs/evaluate_claims.log",
    benchmark:
        "data/benchmarks/evaluate_claims/all.tsv"
    script:
        "../scripts/evaluate_claims.py"


rule summarize_pipeline:
    input:
        tables=all_tables,
        loc_tables=localization_tables,
        studies=study_logs,
        benchmarks=lambda w: all_benchmarks(made=True),
    output:
        "reports/pipeline.json",
    params:
        benchmarks=all_benchmarks,
        sets=SETS,
        loc_sets=localization_table_names(),
        source=script_source("summarize_pipeline"),
    log:
        "logs/summarize_pipeline.log",
    script:
        "../scripts/summarize_pipeline.py"


rule build_report:
    input:
        tables=all_tables,
        claims=rules.evaluate_claims.output[0],
        pipeline=rules.summarize_pipeline.output[0],
        figures=all_figures,
        sweeps=sweep_summaries,
        studies=studies_json,
        studies_figures=lambda w: list(studies_figures().values()),
        loc_tables=localization_tables,
        loc_figures=localization_figures,
        # the section "Your robot": each robot's calibration outputs (workflow/rules/robots.smk)
        robots=lambda w: [f for r in robot_manifest() for f in r["files"].values()],
        # the speed benchmarks' results, when `make bench` has written them (not made by the DAG)
        speed=lambda w: sorted(str(p) for p in Path("benchmarks/results").glob("*.json")),
    output:
        report="reports/comparison.html",
        # the companion pages: each set's run figures, one self-contained page per set, linked from the report
        runs=directory("reports/runs"),
    params:
        manifest=report_manifest(),
        sets=SETS,
        title=config["report"]["title"],
        studies_figures=studies_figures(),
        loc_sets=LOC_SETS,
        robots=robot_manifest(),
        source=script_source("build_report", data=REPORT_TEMPLATES),
    # the last job, alone: it encodes the figures on the machine's cores (OMP_NUM_THREADS = its
    # threads; Snakemake scales them down to --cores; a cluster run has no --cores: a local rule)
    threads: min(8, os.cpu_count() or 1)
    log:
        "logs/build_report.log",
    script:
        "../scripts/build_report.py"
