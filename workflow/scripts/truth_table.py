"""Snakemake adapter: a synthetic scene's file -> results/truth/<scene>.csv (truth against fit)."""

from dashpot.joblog import job_log
from dashpot.store import read_fit
from dashpot.truth import write_truth_csv

snakemake = globals()["snakemake"]  # injected by Snakemake's script directive

with job_log(snakemake.log[0], f"truth against fit of {snakemake.wildcards.scene}") as log:
    table = read_fit(snakemake.input[0])["truth"]
    write_truth_csv(snakemake.output[0], table)
    for row in table.itertuples():
        log.info("%s: truth %.6g, fit %.6g ± %.2g %s, pull %.2f", row.parameter, row.truth,
                 row.value, row.stderr, row.unit, row.pull)
