rule theory:
    """Critical speed and restitution curves of every contact model (the paper's figures)."""
    output:
        critical="results/theory/critical_velocity.csv",
        restitution="results/theory/restitution_vs_zeta.csv",
    params:
        speeds=config["theory"]["speeds"],
        zeta_max=config["theory"]["zeta_max"],
        points=config["theory"]["points"],
    log:
        "results/logs/theory.log",
    benchmark:
        "results/benchmarks/theory.tsv"
    conda:
        "../envs/dashpot.yaml"
    script:
        "../scripts/theory.py"
