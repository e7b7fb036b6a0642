rule summary:
    """One row per scene and model: β, k, ω0, ζ, v0 with errors and the model selection."""
    input:
        expand("results/{scene}.h5", scene=SCENES),
    output:
        h5="results/summary.h5",
        csv=report(
            "results/summary.csv",
            caption="../report/summary.rst",
            category="Summary",
            labels={"table": "all scenes"},
        ),
    log:
        "results/logs/summary.log",
    benchmark:
        "results/benchmarks/summary.tsv"
    conda:
        "../envs/dashpot.yaml"
    script:
        "../scripts/summary.py"
