"""Snakemake adapter: every scene file -> results/summary.h5 and results/summary.csv.

Every file is opened and checked first: a damaged one is named in one log line and in its
row of the summary, and the summary is built from the others instead of failing. A scene
with several runs has rows per run (column `run`). Scenes the
workflow could not run (params.problems) are marked stale (earlier results) or failed.
"""

from dashpot.joblog import job_log
from dashpot.store import write_summary
from dashpot.summary import summary_from_files

snakemake = globals()["snakemake"]  # injected by Snakemake's script directive

with job_log(snakemake.log[0], "cross-scene summary") as log:
    files = [*snakemake.input, *snakemake.params.stale]
    # One row per run and model: a multi-run scene's runs each with its own fits.
    table = summary_from_files(files, snakemake.params.problems, by_run=True)
    marked = table[table["status"] != "ok"].drop_duplicates("scene")
    for row in marked.itertuples():
        log.warning("scene %s (%s): %s", row.scene, row.status, row.problem)
    # The workflow's own outputs, which Snakemake decided to make again.
    write_summary(snakemake.output.h5, snakemake.output.csv, table, overwrite=True)
    log.info("%d scenes (%d not up to date), %d rows", table["scene"].nunique(), len(marked),
             len(table))
