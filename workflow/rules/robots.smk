# Your robot (config key `robots`, pose_uncertainty.experiments.robot_config): each robot's bag calibrated by
# one job, as `pose-uncertainty robot calibrate` does; a simulated robot's bag (bag: null) written by a job of
# its own with its true parameters beside it; one table of every robot for the claims and the report.
from pose_uncertainty.experiments import robot_config as _robot_config

try:
    ROBOTS = _robot_config.robots_config(config)  # {name: entry, every key filled in}
except ValueError as _exc:
    raise WorkflowError(f"invalid config: {_exc}") from None

# the robot jobs' commands (python -m pose_uncertainty.cli.robot_job) and the code they run
ROBOT_JOB = f"{_shlex.quote(_sys.executable)} -m pose_uncertainty.cli.robot_job"
SOURCE_ROBOT_JOB = closure_sha256("pose_uncertainty.cli.robot_job")
# the report's section "Your robot" is a template of its own (included by comparison.html.j2)
ROBOTS_TEMPLATE = "pose_uncertainty/present/templates/robots.html.j2"
ROBOT_OUTPUTS = ("calibration.json", "ros2_control.yaml", "nav2_amcl.yaml", "robot_localization.yaml", "horizon.json",
                 "report.html", "recovery.json", "drive.png", "growth.png", "horizon.png")


def robot_spec(wildcards):
    """One robot's checked entry of `robots.runs` (a rule param)."""
    return ROBOTS[wildcards.robot]


def robot_bag(wildcards):
    """The bag a robot is calibrated from: the configured one, or the one its simulation job writes."""
    bag = ROBOTS[wildcards.robot]["bag"]
    return bag if bag is not None else f"data/robots/{wildcards.robot}/bag.mcap"


def robot_inputs(wildcards):
    """The calibration job's inputs: the bag, a simulated robot's truth, the robot file."""
    spec = ROBOTS[wildcards.robot]
    out = {"bag": robot_bag(wildcards)}
    if spec["bag"] is None:
        out["truth"] = f"data/robots/{wildcards.robot}/truth.json"
    if spec["robot_file"] is not None:
        out["robot_file"] = spec["robot_file"]
    return out


def robot_truth_arg(wildcards, input):
    return f"--truth {_shlex.quote(input.truth)}" if "truth" in input.keys() else ""


def robot_dirs(wildcards=None):
    """The calibration folders of the robots, in config order."""
    return [f"data/robots/{name}" for name in ROBOTS]


def robot_calibrations(wildcards=None):
    return [f"{d}/calibration.json" for d in robot_dirs()]


def robot_tables(wildcards=None):
    """reports/tables/robots/robots.csv when the config holds a robot, else nothing."""
    return ["reports/tables/robots/robots.csv"] if ROBOTS else []


def robot_manifest():
    """The robots the report's section "Your robot" shows, with their output files (a rule param)."""
    return [
        {"name": name, "title": spec["title"], "source": spec["source"], "description": spec["description"],
         "simulated": spec["bag"] is None, "dir": f"data/robots/{name}",
         "files": {f: f"data/robots/{name}/{f}" for f in ROBOT_OUTPUTS}}
        for name, spec in ROBOTS.items()
    ]


def robot_benchmarks():
    out = []
    for name, spec in ROBOTS.items():
        if spec["bag"] is None:
            out.append(f"data/benchmarks/simulate_robot/{name}.tsv")
        out.append(f"data/benchmarks/calibrate_robot/{name}.tsv")
    return out


wildcard_constraints:
    robot="[A-Za-z0-9_-]+",


rule simulate_robot:
    output:
        bag="data/robots/{robot}/bag.mcap",
        truth="data/robots/{robot}/truth.json",
    params:
        spec=as_json(robot_spec),
        source=SOURCE_ROBOT_JOB,
    log:
        "logs/simulate_robot/{robot}.log",
    benchmark:
        "data/benchmarks/simulate_robot/{robot}.tsv"
    shell:
        "{ROBOT_JOB} simulate {params.spec:q} {output.bag:q} {output.truth:q} 2> {log:q}"


rule calibrate_robot:
    input:
        unpack(robot_inputs),
    output:
        **{f.replace(".", "_"): f"data/robots/{{robot}}/{f}" for f in ROBOT_OUTPUTS},
    params:
        spec=as_json(robot_spec),
        truth=robot_truth_arg,
        outdir="data/robots/{robot}",
        source=SOURCE_ROBOT_JOB,
    log:
        "logs/calibrate_robot/{robot}.log",
    benchmark:
        "data/benchmarks/calibrate_robot/{robot}.tsv"
    shell:
        "{ROBOT_JOB} calibrate {params.spec:q} {input.bag:q} {params.outdir:q} {params.truth} 2> {log:q}"


rule collect_robots:
    input:
        calibrations=robot_calibrations,
    output:
        report(
            "reports/tables/robots/robots.csv",
            caption="../report/table.rst",
            category="robots",
            subcategory="tables",
            labels={"table": "robots"},
        ),
    params:
        names=list(ROBOTS),
        dirs=robot_dirs(),
        source=script_source("collect_robots"),
    log:
        "logs/collect_robots.log",
    script:
        "../scripts/collect_robots.py"
