# A scene's figures are drawn by its chunk (rule fit_chunk) and moved into place here.


rule scene_plots:
    """Intervals with residuals, restitution against impact speed, model selection."""
    input:
        chunk_folder,
        "results/{scene}.h5",
    output:
        intervals=update(
            report(
                "results/plots/{scene}/intervals.png",
                caption="../report/intervals.rst",
                category="Scenes",
                subcategory="{scene}",
                labels={"scene": "{scene}", "figure": "intervals"},
            )
        ),
        restitution=update(
            report(
                "results/plots/{scene}/restitution.png",
                caption="../report/restitution.rst",
                category="Scenes",
                subcategory="{scene}",
                labels={"scene": "{scene}", "figure": "restitution"},
            )
        ),
        selection=update(
            report(
                "results/plots/{scene}/selection.png",
                caption="../report/selection.rst",
                category="Scenes",
                subcategory="{scene}",
                labels={"scene": "{scene}", "figure": "selection"},
            )
        ),
        pdf=update(
            multiext("results/plots/{scene}/", "intervals.pdf", "restitution.pdf",
                     "selection.pdf")
        ),
    params:
        staged=staged,
    log:
        "results/logs/publish/scene_plots/{scene}.log",
    conda:
        "../envs/dashpot.yaml"
    localrule: True
    shell:
        publish("plots", "its figures")


rule detection_plot:
    """Envelope of an audio recording with the detected impacts."""
    input:
        chunk_folder,
        "results/{scene}.h5",
    output:
        png=update(
            report(
                "results/plots/{scene}/detection.png",
                caption="../report/detection.rst",
                category="Scenes",
                subcategory="{scene}",
                labels={"scene": "{scene}", "figure": "detection"},
            )
        ),
        pdf=update("results/plots/{scene}/detection.pdf"),
    params:
        staged=staged,
    wildcard_constraints:
        scene=_names_pattern(AUDIO_SCENES),
    log:
        "results/logs/publish/detection_plot/{scene}.log",
    conda:
        "../envs/dashpot.yaml"
    localrule: True
    shell:
        publish("plots", "its detection figure")
