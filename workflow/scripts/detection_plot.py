"""Snakemake adapter: an audio recording and its scene file -> the detection figure."""

from pathlib import Path

from dashpot.figures import detection_figure, load_record
from dashpot.joblog import job_log
from dashpot.plots import save_figure

snakemake = globals()["snakemake"]  # injected by Snakemake's script directive

with job_log(snakemake.log[0], f"detection figure of {snakemake.wildcards.scene}") as log:
    figure = detection_figure(load_record(snakemake.input.fit), snakemake.params.recording)
    written = save_figure(figure, Path(snakemake.output.png).with_suffix(""))
    log.info("wrote %s", ", ".join(map(str, written)))
