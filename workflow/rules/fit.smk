rule fit_chunk:
    """A chunk of scenes fitted by one process (dashpot.batch.process_chunk), each into the
    chunk's staging folder with its own log (results/logs/fit/<scene>.log): a synthetic
    scene's recording simulated first, then impacts and every contact model, the truth table
    of a synthetic scene and, where figures are drawn, its figures. A scene whose result is
    up to date is skipped; one that fails leaves its error line for its `fit` step, and the
    chunk goes on. The folder is temporary: deleted once every scene's files are in place.
    """
    input:
        chunk_input,
    output:
        temp(directory("results/chunks/fit/{chunk}")),
    params:
        scenes=chunk_tasks,
        plots=SCENE_PLOTS,
        dashpot_source=DASHPOT_SOURCE,
    log:
        "results/logs/fit_chunk/{chunk}.log",
    benchmark:
        "results/benchmarks/fit_chunk/{chunk}.tsv"
    wildcard_constraints:
        chunk=_names_pattern(CHUNKS),
    # Fits first: the theory job, which nothing waits for, then runs beside the summary
    # instead of holding a core while chunks wait.
    priority: 10
    conda:
        "../envs/dashpot.yaml"
    script:
        "../scripts/fit_chunk.py"


rule fit:
    """One scene's HDF5 file moved into place from its chunk, or the scene's error.

    The output is flagged update(): Snakemake keeps a copy of the earlier file while the step
    runs and puts it back if it fails, so a fit that fails on a rerun (an unreadable new
    recording, a crash) never deletes the scene's earlier results; the chunk itself never
    writes results/<scene>.h5.
    """
    input:
        chunk_folder,
    output:
        update("results/{scene}.h5"),
    params:
        staged=staged,
    log:
        "results/logs/publish/fit/{scene}.log",
    conda:
        "../envs/dashpot.yaml"
    localrule: True
    shell:
        publish("fit", "its fit")


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
    (the same rows as the scene file's `truth` group, units in the headers), from its chunk."""
    input:
        chunk_folder,
        "results/{scene}.h5",
    output:
        update(
            report(
                "results/truth/{scene}.csv",
                caption="../report/truth.rst",
                category="Summary",
                labels={"table": "truth against fit: {scene}"},
            )
        ),
    params:
        staged=staged,
    wildcard_constraints:
        scene=_names_pattern(SYNTHETIC_SCENES),
    log:
        "results/logs/publish/truth/{scene}.log",
    conda:
        "../envs/dashpot.yaml"
    localrule: True
    shell:
        publish("truth", "its truth table")
