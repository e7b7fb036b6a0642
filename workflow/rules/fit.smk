rule fit:
    """Impacts of one scene's recording and every contact model fitted, to one HDF5 file."""
    input:
        unpack(fit_input),
    output:
        "results/{scene}.h5",
    params:
        mapping=config_scene,
    log:
        "results/logs/fit/{scene}.log",
    benchmark:
        "results/benchmarks/fit/{scene}.tsv"
    conda:
        "../envs/dashpot.yaml"
    script:
        "../scripts/fit.py"
