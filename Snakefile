# dashpot workflow: thin entry point; the rules live in workflow/rules/.
from snakemake.utils import min_version, validate

min_version("9.0")


configfile: "config/config.yaml"


validate(config, "workflow/schemas/config.schema.yaml")


include: "workflow/rules/theory.smk"


rule all:
    input:
        rules.theory.output,
