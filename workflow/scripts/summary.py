"""Snakemake adapter: every scene file -> results/summary.h5 and results/summary.csv."""

from dashpot.joblog import job_log
from dashpot.store import write_summary
from dashpot.summary import summary_from_files

snakemake = globals()["snakemake"]  # injected by Snakemake's script directive

with job_log(snakemake.log[0], "cross-scene summary") as log:
    table = summary_from_files(list(snakemake.input))
    write_summary(snakemake.output.h5, snakemake.output.csv, table)
    log.info("%d scenes, %d rows", table["scene"].nunique(), len(table))
