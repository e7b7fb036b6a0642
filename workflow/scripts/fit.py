"""Snakemake adapter: one scene's recording -> impacts and fits (every run, and the runs
jointly) -> results/<scene>.h5."""

from dataclasses import replace

from dashpot.analysis import analyze_runs
from dashpot.cli import joint_text
from dashpot.joblog import job_log
from dashpot.pipeline import workflow_scene
from dashpot.store import write_scene_fit
from dashpot.truth import truth_comparison

snakemake = globals()["snakemake"]  # injected by Snakemake's script directive
name = snakemake.wildcards.scene

with job_log(snakemake.log[0], f"fit scene {name}") as log:
    scene = workflow_scene(name, scene_file=snakemake.input.get("scene"),
                           mapping=snakemake.params.mapping)
    log.info("recording %s, sensor %s, models %s", scene.recording, scene.sensor,
             ", ".join(scene.models))
    methods = snakemake.params.get("uncertainty")
    if methods and scene.uncertainty == ("covariance",):
        # The config's methods, for every scene whose scene.yaml does not choose its own.
        scene = replace(scene, uncertainty=tuple(dict.fromkeys(["covariance", *methods])))
    if snakemake.params.get("noise") and not scene.noise:
        # The config's noise model, for every scene (a scene.yaml can only add it).
        scene = replace(scene, noise=True)
    impacts, runs_fit = analyze_runs(scene.recording, scene)
    scene_fit = runs_fit.first  # the first run's, at the root of the file
    if len(runs_fit.runs) > 1:
        log.info("%d runs: each fitted on its own, and jointly", len(runs_fit.runs))
        for run, fit in runs_fit.runs.items():
            for model, result in fit.results.items():
                log.info("run %s, %s: %s", run, model, result.message)
        # As `dashpot fit` prints them: each run's fit beside the joint fit.
        log.info("%s", joint_text(runs_fit))
    for note in impacts.attrs.get("notes", []):
        log.info("reader: %s", note)
    for model, fit in scene_fit.results.items():
        log.info("%s: %s", model, fit.message)
    log.info("verdict: %s", scene_fit.verdict)
    log.info("summary, with each model's notes:\n%s", scene_fit.report())  # as `dashpot fit`
    # A synthetic scene's truth.json: its fit of the generating model against the truth.
    truth = truth_comparison(snakemake.params.truth, scene_fit) if snakemake.params.truth \
        else None
    if truth is not None:
        for row in truth.itertuples():
            log.info("truth %s = %.6g %s: pull %.2f %s", row.parameter, row.truth, row.unit,
                     row.pull, row.note)
    write_scene_fit(snakemake.output[0], scene_fit, impacts, input_path=scene.recording,
                    config={"models": list(scene_fit.results),
                            "scene_source": snakemake.input.get("scene") or "config.yaml"},
                    truth=truth, runs=runs_fit)
