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


rule theory_plots:
    """The paper's figures recomputed: contact time, ε(ζ), critical speed, ε(ṽ)."""
    output:
        contact_time=report(
            "results/theory/contact_time.png",
            caption="../report/theory_contact_time.rst",
            category="Theory",
            labels={"figure": "contact time"},
        ),
        restitution=report(
            "results/theory/restitution.png",
            caption="../report/theory_restitution.rst",
            category="Theory",
            labels={"figure": "restitution against damping"},
        ),
        critical_speed=report(
            "results/theory/critical_speed.png",
            caption="../report/theory_critical_speed.rst",
            category="Theory",
            labels={"figure": "critical speed"},
        ),
        restitution_vs_speed=report(
            "results/theory/restitution_vs_speed.png",
            caption="../report/theory_restitution_vs_speed.rst",
            category="Theory",
            labels={"figure": "restitution against speed"},
        ),
        pdf=multiext("results/theory/", "contact_time.pdf", "restitution.pdf",
                     "critical_speed.pdf", "restitution_vs_speed.pdf"),
    params:
        speeds=config["theory"]["speeds"],
        zeta_max=config["theory"]["zeta_max"],
        points=config["theory"]["points"],
    log:
        "results/logs/theory_plots.log",
    benchmark:
        "results/benchmarks/theory_plots.tsv"
    conda:
        "../envs/dashpot.yaml"
    script:
        "../scripts/theory_plots.py"
