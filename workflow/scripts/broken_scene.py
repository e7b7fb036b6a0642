"""Snakemake adapter: a scene that cannot run fails with its one-line problem, touching nothing.

The scene's earlier results/<scene>.h5 and figures, if any, are kept (and the summary marks
its rows stale).
"""

from dashpot.errors import InputError
from dashpot.joblog import job_log

snakemake = globals()["snakemake"]  # injected by Snakemake's script directive
name = snakemake.wildcards.scene


class SceneProblem(InputError):
    """The problem line found while the workflow was built (it already names the file)."""

    def __str__(self):
        return self.problem


with job_log(snakemake.log[0], f"scene {name} cannot run") as log:
    if snakemake.params.earlier:
        log.info("%s from an earlier run is kept (its summary rows are marked stale)",
                 snakemake.params.earlier)
    raise SceneProblem(name, snakemake.params.problem)
