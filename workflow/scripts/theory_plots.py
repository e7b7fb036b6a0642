"""Snakemake adapter: the contact models' theory figures (no science here)."""

from pathlib import Path

from dashpot import plots
from dashpot.joblog import job_log

snakemake = globals()["snakemake"]  # injected by Snakemake's script directive
params = snakemake.params

with job_log(snakemake.log[0], "theory figures") as log:
    figures = {
        "contact_time": plots.contact_time_figure(zeta_max=params.zeta_max,
                                                  points=params.points),
        "restitution": plots.restitution_figure(speeds=params.speeds, zeta_max=params.zeta_max,
                                                points=params.points),
        "critical_speed": plots.critical_speed_figure(zeta_max=params.zeta_max,
                                                      points=params.points),
        "restitution_vs_speed": plots.restitution_vs_speed_figure(),
    }
    for name, figure in figures.items():
        written = plots.save_figure(figure, Path(snakemake.output[name]).with_suffix(""))
        log.info("wrote %s", ", ".join(map(str, written)))
