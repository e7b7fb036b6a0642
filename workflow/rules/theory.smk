rule theory:
    """Critical speed and restitution curves of every contact model (the paper's), as CSV,
    and the paper's figures recomputed: contact time, ε(ζ), critical speed, ε(ṽ). One job:
    the figures' Python start-up is paid once."""
    output:
        critical="results/theory/critical_velocity.csv",
        restitution="results/theory/restitution_vs_zeta.csv",
        contact_time=report(
            "results/theory/contact_time.png",
            caption="../report/theory_contact_time.rst",
            category="Theory",
            labels={"figure": "contact time"},
        ),
        restitution_figure=report(
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
        dashpot_source=DASHPOT_SOURCE,
    log:
        "results/logs/theory.log",
    benchmark:
        "results/benchmarks/theory.tsv"
    conda:
        "../envs/dashpot.yaml"
    script:
        "../scripts/theory.py"
