"""Snakemake adapter: a chunk of scenes -> each scene's files in the chunk's staging folder
(dashpot.batch.process_chunk; the per-scene steps move them into place)."""

from dashpot.batch import process_chunk
from dashpot.joblog import job_log

snakemake = globals()["snakemake"]  # injected by Snakemake's script directive
scenes = snakemake.params.scenes

with job_log(snakemake.log[0], f"fit chunk {snakemake.wildcards.chunk} "
                               f"({len(scenes)} scenes)") as log:
    status = process_chunk(scenes, snakemake.output[0], plots=snakemake.params.plots)
    for name, state in status.items():
        log.info("%s: %s", name, state)
