"""Snakemake adapter: theory curves of every contact model to CSV, and the paper's theory
figures (no science here)."""

import logging
import sys
from pathlib import Path

import numpy as np

import dashpot
from dashpot import plots
from dashpot.atomic import atomic_path
from dashpot.joblog import job_log

snakemake = globals()["snakemake"]  # injected by Snakemake's script directive
params, output = snakemake.params, snakemake.output


def write_atomically(path, header, columns):
    """Write a CSV to a unique temporary name, then rename, so no half file is left behind.

    A write that fails (a full disk) ends the job with one line and status 2. An existing
    file is replaced: the workflow's own output, which Snakemake decided to make again.
    """
    try:
        with atomic_path(path, overwrite=True) as temporary:
            np.savetxt(temporary, np.column_stack(columns), delimiter=",",
                       header=",".join(header), comments="", fmt="%.17g")
    except OSError as error:
        logging.error("cannot write %s: %s", path, error)
        print(f"{path}: cannot write the output ({error.strerror or error})", file=sys.stderr)
        sys.exit(2)


with job_log(snakemake.log[0], "theory curves and figures") as log:
    zeta = np.linspace(0.0, params.zeta_max, params.points)
    critical = [dashpot.critical_velocity(model, zeta) for model in dashpot.MODELS]
    write_atomically(output.critical, ["zeta", *dashpot.MODELS], [zeta, *critical])
    log.info("critical speeds for %d damping ratios", zeta.size)

    header, columns = ["zeta"], [zeta]
    for speed in params.speeds:
        for model in dashpot.MODELS:
            header.append(f"eps_{model}_v{speed:g}")
            columns.append(dashpot.collide(model, zeta, float(speed)).eps)
    write_atomically(output.restitution, header, columns)
    log.info("restitution curves at speeds %s", params.speeds)

    figures = {
        "contact_time": plots.contact_time_figure(zeta_max=params.zeta_max,
                                                  points=params.points),
        "restitution_figure": plots.restitution_figure(speeds=params.speeds,
                                                       zeta_max=params.zeta_max,
                                                       points=params.points),
        "critical_speed": plots.critical_speed_figure(zeta_max=params.zeta_max,
                                                      points=params.points),
        "restitution_vs_speed": plots.restitution_vs_speed_figure(),
    }
    for name, figure in figures.items():
        written = plots.save_figure(figure, Path(getattr(output, name)).with_suffix(""),
                                    overwrite=True)
        log.info("wrote %s", ", ".join(map(str, written)))
