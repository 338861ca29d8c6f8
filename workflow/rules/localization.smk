# Localization runs (config key `localization.sets`): one run → one MCAP log (byte-reproducible) and its
# timings (a job per run, or per chunk of runs with runs_per_job above 1: workflow/rules/simulate.smk);
# the runs' figures drawn from the logs by one job per set (one interpreter start-up per set); one table
# per set; the set figures. The code that computes a run is a rule param (`source`: the import closure
# of the code each rule runs), so a code change reruns what it affects.


# runs_per_job = 1: one job per run; above 1 the chunks' rules of workflow/rules/simulate.smk make the logs
if RUNS_PER_JOB == 1:

    rule simulate_localization:
        output:
            log="data/localization/{set}/{run}.mcap",
            timings="data/localization/{set}/{run}.timings.json",
        params:
            config=as_json(localization_config),
            source=SOURCE_JOB,
        resources:
            # what the run estimates it needs, each filter included (a cluster job's --mem and --time)
            mem_mb=lambda wc: localization_resources(wc)["mem_mb"],
            runtime=lambda wc: localization_resources(wc)["runtime"],
        log:
            "logs/simulate_localization/{set}/{run}.log",
        benchmark:
            "data/benchmarks/simulate_localization/{set}/{run}.tsv"
        shell:
            "{JOB} simulate-localization {params.config:q} {output.log:q} {output.timings:q} 2> {log:q}"


rule render_localization_figures:
    input:
        runs=lambda w: runs_made(w.set, localization=True),
    output:
        report(
            directory("reports/figures/localization/{set}/runs"),
            patterns=["{run}/{name}.png"],
            caption="../report/localization_run.rst",
            category="localization",
            subcategory="{set}",
            labels={"run": "{run}", "figure": "{name}"},
        ),
    params:
        source=script_source("render_localization_figures"),
        logs=lambda w: localization_logs(w.set),
        kinds=list(LOC_RUN_FIGURES),
    log:
        "logs/render_localization_figures/{set}.log",
    benchmark:
        "data/benchmarks/render_localization_figures/{set}.tsv"
    script:
        "../scripts/render_localization_figures.py"


rule render_localization_set_figure:
    input:
        runs=lambda w: runs_made(w.set, timings=True, localization=True),
    output:
        report(
            "reports/figures/localization/{set}/{kind}.png",
            caption="../report/localization_set.rst",
            category="localization",
            subcategory="{set}",
            labels={"figure": "{kind}"},
        ),
    wildcard_constraints:
        kind="accuracy_time|success",
    params:
        source=script_source("render_localization_set_figure"),
        logs=lambda w: localization_logs(w.set),
        timings=lambda w: localization_timings(w.set),
        title=lambda w: config["localization"]["sets"][w.set]["title"],
    log:
        "logs/render_localization_set_figure/{set}/{kind}.log",
    benchmark:
        "data/benchmarks/render_localization_set_figure/{set}/{kind}.tsv"
    script:
        "../scripts/render_localization_set_figure.py"


rule collect_localization_metrics:
    input:
        runs=lambda w: runs_made(w.set, timings=True, localization=True),
    output:
        report(
            "reports/tables/localization/{set}.csv",
            caption="../report/table.rst",
            category="localization",
            subcategory="tables",
            labels={"table": "{set}"},
        ),
    params:
        logs=lambda w: localization_logs(w.set),
        timings=lambda w: localization_timings(w.set),
        source=script_source("collect_metrics"),
    log:
        "logs/collect_localization_metrics/{set}.log",
    benchmark:
        "data/benchmarks/collect_localization_metrics/{set}.tsv"
    script:
        "../scripts/collect_metrics.py"
