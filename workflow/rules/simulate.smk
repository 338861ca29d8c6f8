# One run → one MCAP log (byte-reproducible) + its wall-clock timings (pose_uncertainty.cli.job).
from pose_uncertainty.experiments import cost as _cost


rule simulate_run:
    output:
        log="data/runs/{set}/{run}.mcap",
        timings="data/runs/{set}/{run}.timings.json",
    params:
        config=as_json(run_config),
        # the code that computes a run: a change to it reruns every simulation (the logs record it)
        source=SOURCE_JOB,
    resources:
        # what the run estimates it needs (a cluster job's --mem and --time)
        mem_mb=lambda wc: _cost.job_resources(run_config(wc))["mem_mb"],
        runtime=lambda wc: _cost.job_resources(run_config(wc))["runtime"],
    log:
        "logs/simulate_run/{set}/{run}.log",
    benchmark:
        "data/benchmarks/simulate_run/{set}/{run}.tsv"
    shell:
        "{JOB} simulate-run {params.config:q} {output.log:q} {output.timings:q} 2> {log:q}"
