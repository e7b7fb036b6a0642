rule fit:
    """Impacts of one scene's recording and every contact model fitted, to one HDF5 file.

    The output is flagged update(): Snakemake keeps a copy of the earlier file while the job
    runs and puts it back if the job fails, so a fit that fails on a rerun (an unreadable new
    recording, a crash) never deletes the scene's earlier results.
    """
    input:
        unpack(fit_input),
    output:
        update("results/{scene}.h5"),
    params:
        mapping=config_scene,
        truth=truth_file,
        uncertainty=config.get("uncertainty", ["covariance"]),
        noise=config.get("noise", False),
    log:
        "results/logs/fit/{scene}.log",
    benchmark:
        "results/benchmarks/fit/{scene}.tsv"
    conda:
        "../envs/dashpot.yaml"
    script:
        "../scripts/fit.py"


rule broken_scene:
    """A scene that cannot run: fails with one line naming the file and the problem.

    Its output is never written (the job always fails, so each run reports the scene again);
    the scene's earlier results are no output of any job of this run, so they are kept.
    """
    output:
        "results/logs/fit/{scene}.broken",
    params:
        problem=broken_scene_problem,
        earlier=lambda wildcards: earlier_result(wildcards.scene),
    log:
        "results/logs/fit/{scene}.log",
    wildcard_constraints:
        scene=_names_pattern(BROKEN_SCENES),
    conda:
        "../envs/dashpot.yaml"
    script:
        "../scripts/broken_scene.py"


rule truth_table:
    """A synthetic scene's truth against the generating model's fit, as a table for the report
    (the same rows as the scene file's `truth` group, units in the headers)."""
    input:
        "results/{scene}.h5",
    output:
        report(
            "results/truth/{scene}.csv",
            caption="../report/truth.rst",
            category="Summary",
            labels={"table": "truth against fit: {scene}"},
        ),
    log:
        "results/logs/truth_table/{scene}.log",
    wildcard_constraints:
        scene=_names_pattern(SYNTHETIC_SCENES),
    conda:
        "../envs/dashpot.yaml"
    script:
        "../scripts/truth_table.py"
