rule scene_plots:
    """Intervals with residuals, restitution against impact speed, model selection."""
    input:
        "results/{scene}.h5",
    output:
        intervals=report(
            "results/plots/{scene}/intervals.png",
            caption="../report/intervals.rst",
            category="Scenes",
            subcategory="{scene}",
            labels={"scene": "{scene}", "figure": "intervals"},
        ),
        restitution=report(
            "results/plots/{scene}/restitution.png",
            caption="../report/restitution.rst",
            category="Scenes",
            subcategory="{scene}",
            labels={"scene": "{scene}", "figure": "restitution"},
        ),
        selection=report(
            "results/plots/{scene}/selection.png",
            caption="../report/selection.rst",
            category="Scenes",
            subcategory="{scene}",
            labels={"scene": "{scene}", "figure": "selection"},
        ),
        pdf=multiext("results/plots/{scene}/", "intervals.pdf", "restitution.pdf",
                     "selection.pdf"),
    log:
        "results/logs/scene_plots/{scene}.log",
    benchmark:
        "results/benchmarks/scene_plots/{scene}.tsv"
    conda:
        "../envs/dashpot.yaml"
    script:
        "../scripts/scene_plots.py"


rule detection_plot:
    """Envelope of an audio recording with the detected impacts."""
    input:
        fit="results/{scene}.h5",
        recording=recording_input,
    output:
        png=report(
            "results/plots/{scene}/detection.png",
            caption="../report/detection.rst",
            category="Scenes",
            subcategory="{scene}",
            labels={"scene": "{scene}", "figure": "detection"},
        ),
        pdf="results/plots/{scene}/detection.pdf",
    params:
        recording=lambda wildcards: SCENES[wildcards.scene]["recording"],
    log:
        "results/logs/detection_plot/{scene}.log",
    benchmark:
        "results/benchmarks/detection_plot/{scene}.tsv"
    conda:
        "../envs/dashpot.yaml"
    script:
        "../scripts/detection_plot.py"
