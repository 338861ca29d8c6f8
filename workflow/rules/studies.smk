# The studies (Šafránek 2022's, the growth laws, the accuracy cases, ...): one job and one log each,
# with their parameters from config key `studies.runs`; collected for the report.


rule run_study:
    output:
        "data/studies/{study}.json",
    params:
        spec=as_json(study_config),
        source=SOURCE_JOB,
    resources:
        # the study's bound from its sampling size (a cluster job's --mem and --time)
        mem_mb=lambda wc: study_resources(wc)["mem_mb"],
        runtime=lambda wc: study_resources(wc)["runtime"],
    log:
        "logs/run_study/{study}.log",
    benchmark:
        "data/benchmarks/run_study/{study}.tsv"
    shell:
        "{JOB} run-study {wildcards.study:q} {params.spec:q} {output:q} 2> {log:q}"


rule collect_studies:
    input:
        logs=study_logs,
    output:
        "reports/studies.json",
    params:
        source=script_source("collect_studies"),
    log:
        "logs/collect_studies.log",
    script:
        "../scripts/collect_studies.py"


rule render_study_figure:
    # one rule for every study kind with a figure (pose_uncertainty.present.pipeline_figures.STUDY_FIGURES)
    input:
        log="data/studies/{study}.json",
    output:
        report(
            "reports/figures/studies/{study}.png",
            caption="../report/study.rst",
            category="studies",
            subcategory="{study}",
            labels={"figure": "{study}"},
        ),
    params:
        kind=study_kind,
        source=script_source("render_study_figure"),
    log:
        "logs/render_study_figure/{study}.log",
    benchmark:
        "data/benchmarks/render_study_figure/{study}.tsv"
    script:
        "../scripts/render_study_figure.py"
