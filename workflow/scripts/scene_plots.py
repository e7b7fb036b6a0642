"""Snakemake adapter: one scene file -> its intervals, restitution and selection figures."""

from pathlib import Path

from dashpot.figures import load_record, scene_figures
from dashpot.joblog import job_log
from dashpot.plots import save_figure

snakemake = globals()["snakemake"]  # injected by Snakemake's script directive

with job_log(snakemake.log[0], f"figures of {snakemake.wildcards.scene}") as log:
    record = load_record(snakemake.input[0])
    for name, figure in scene_figures(record).items():
        written = save_figure(figure, Path(snakemake.output[name]).with_suffix(""))
        log.info("wrote %s", ", ".join(map(str, written)))
