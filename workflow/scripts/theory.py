"""Snakemake adapter: theory curves of every contact model to CSV (no science here)."""

import logging
import sys

import numpy as np

import dashpot
from dashpot.atomic import atomic_path

snakemake = globals()["snakemake"]  # injected by Snakemake's script directive
logging.basicConfig(filename=snakemake.log[0], level=logging.INFO, filemode="w")


def write_atomically(path, header, columns):
    """Write a CSV to a unique temporary name, then rename, so no half file is left behind.

    A write that fails (a full disk) ends the job with one line and status 2.
    """
    try:
        with atomic_path(path) as temporary:
            np.savetxt(temporary, np.column_stack(columns), delimiter=",",
                       header=",".join(header), comments="", fmt="%.17g")
    except OSError as error:
        logging.error("cannot write %s: %s", path, error)
        print(f"{path}: cannot write the output ({error.strerror or error})", file=sys.stderr)
        sys.exit(2)


zeta = np.linspace(0.0, snakemake.params.zeta_max, snakemake.params.points)
critical = [dashpot.critical_velocity(model, zeta) for model in dashpot.MODELS]
write_atomically(snakemake.output.critical, ["zeta", *dashpot.MODELS], [zeta, *critical])
logging.info("critical speeds for %d damping ratios", zeta.size)

header, columns = ["zeta"], [zeta]
for speed in snakemake.params.speeds:
    for model in dashpot.MODELS:
        header.append(f"eps_{model}_v{speed:g}")
        columns.append(dashpot.collide(model, zeta, float(speed)).eps)
write_atomically(snakemake.output.restitution, header, columns)
logging.info("restitution curves at speeds %s", snakemake.params.speeds)
