"""Snakemake adapter: a synthetic scene folder from its config entry (no science here)."""

from dashpot.joblog import job_log
from dashpot.pipeline import write_synthetic_scene

snakemake = globals()["snakemake"]  # injected by Snakemake's script directive
scene = snakemake.wildcards.scene

with job_log(snakemake.log[0], f"simulate scene {scene}") as log:
    written = write_synthetic_scene(snakemake.output[0], snakemake.params.spec, name=scene)
    log.info("wrote %s", written)
