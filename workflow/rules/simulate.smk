rule simulate:
    """A synthetic recording with known parameters, its truth.json and scene.yaml."""
    output:
        directory("results/synthetic/{scene}"),
    params:
        spec=lambda wildcards: config["synthetic"][wildcards.scene],
    log:
        "results/logs/simulate/{scene}.log",
    benchmark:
        "results/benchmarks/simulate/{scene}.tsv"
    conda:
        "../envs/dashpot.yaml"
    script:
        "../scripts/simulate.py"
