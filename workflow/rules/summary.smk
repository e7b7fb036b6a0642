rule summary:
    """One row per scene and model: β, k, ω0, ζ, v0 with errors and the model selection, and
    for synthetic scenes their truth and each fit's pulls (summary.csv: units in the headers).

    Scenes that are not up to date (broken, or whose last fit failed) are listed with their
    status and problem, so a broken scene never stops the summary (see summary_input).
    """
    input:
        summary_input,
    output:
        h5="results/summary.h5",
        csv=report(
            "results/summary.csv",
            caption="../report/summary.rst",
            category="Summary",
            labels={"table": "all scenes"},
        ),
    params:
        problems=summary_problems,
        stale=stale_results,
        dashpot_source=DASHPOT_SOURCE,
    log:
        "results/logs/summary.log",
    benchmark:
        "results/benchmarks/summary.tsv"
    conda:
        "../envs/dashpot.yaml"
    script:
        "../scripts/summary.py"
