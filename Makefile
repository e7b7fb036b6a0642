# Two commands do everything on a fresh machine: `make run` and `make test`.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: install run test bench clean cluster-test

$(STAMP): pyproject.toml constraints.txt
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -c constraints.txt -e ".[test,bench,workflow]"
	touch $(STAMP)

install: $(STAMP)

# The Snakefile is at the root, so Snakemake would not find workflow/profiles/default itself.
# Then every figure with its caption in one page, results/report.html (Snakemake's --report;
# it needs every figure, so it is built once no scene failed).
SNAKEMAKE_RUN = $(BIN)/snakemake --profile workflow/profiles/default --snakefile Snakefile
run: $(STAMP)
	$(SNAKEMAKE_RUN)
	$(SNAKEMAKE_RUN) --report results/report.html

test: $(STAMP)
	$(BIN)/python -m pytest

bench: $(STAMP)
	for script in benchmarks/bench_*.py; do \
	  [ "$$script" = benchmarks/bench_batch.py ] || $(BIN)/python $$script || exit 1; done

cluster-test: $(STAMP)
	bash cluster/test.sh

clean:
	rm -rf $(VENV) results .snakemake

# The whole workflow on 20 and 200 small synthetic scenes at 2 cores, each run and then
# rerun (nothing to do), against the workflow before chunking (a few minutes); the 1,000
# scene row: .venv/bin/python benchmarks/bench_batch.py --scenes 1000, and through SLURM on
# the local test cluster (root): .venv/bin/python benchmarks/bench_batch.py --scenes 1000 --slurm.
.PHONY: bench-batch
bench-batch: $(STAMP)
	$(BIN)/python benchmarks/bench_batch.py
