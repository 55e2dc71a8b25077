# Guaranteed state estimator benchmark harness.  `make help` lists the targets.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
CONFIGS_ALL   := $(wildcard benchmarks/configs/*.yaml)
CONFIGS_QUICK := benchmarks/configs/quick.yaml
RESULTS ?= results
# worker processes of `make bench` (designs and runs); JOBS=1 runs serially, the only mode whose
# per-step times are undisturbed (parallel ones are marked "(parallel)" in the reports;
# reports/speed.md is always timed serially)
JOBS ?= $(shell getconf _NPROCESSORS_ONLN 2>/dev/null || echo 1)
# pytest-xdist workers of `make test` (one per core; TEST_JOBS=0 runs the suite in one process)
TEST_JOBS ?= $(JOBS)
# the order of `make test`: shuffled by a new seed every run (printed in the header; TEST_SEED=N
# repeats an order)
TEST_SEED ?= $(shell od -An -N2 -tu2 /dev/urandom | tr -d ' ')
# single-threaded BLAS: faster and far less noisy on the small matrices of the observers
export OPENBLAS_NUM_THREADS ?= 1
export OMP_NUM_THREADS ?= 1
export MKL_NUM_THREADS ?= 1

.DEFAULT_GOAL := help
.PHONY: help install test lint docs bench bench-cold bench-quick report reports stale fidelity datadriven evidence release check baseline history audit audit-short audit-edge audit-edge-short speed scaling frontier noise-grid robustness kernels clean

help:  ## list the targets
	@echo "setobs-bench: guaranteed state estimator benchmark harness"
	@echo
	@grep -E '^[a-z-]+:.*## ' $(MAKEFILE_LIST) | sed 's/:.*## /\t/' | awk -F'\t' '{printf "  make %-12s %s\n", $$1, $$2}'
	@echo
	@echo "code: observers/ (kernels/ <- lp/ <- sets/ <- family loops, plugins builtin/X.py + numerics/X.py),"
	@echo "systems/ (models, scenarios, data), benchmarks/ in wings: run/ (config -> specs -> runner ->"
	@echo "executors), report/ (tables, markdown, html, figures, numbers), store/ (result stores: graph,"
	@echo "fingerprint, store, bench, stale), gate/ (regression, fidelity, budget, blas, policy, audit,"
	@echo "audit_store, history), timing/ (steps, speed), studies/ (scaling, frontier, noise_grid, robustness, kernels, alanwar2022),"
	@echo "exchange/ (export problems, score other tools' result files);"
	@echo "cli.py parses and prints"

$(STAMP): pyproject.toml
	@$(PYTHON) -c 'import sys; assert sys.version_info >= (3, 10), "Python >= 3.10 is required, found " + sys.version.split()[0]'
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test,dask,docs]'
	@touch $(STAMP)

install: $(STAMP)  ## create .venv and install the project with its test, dask and docs extras

test: $(STAMP)  ## run ruff and the test suite in a shuffled order (TEST_JOBS workers, default one per core; TEST_SEED repeats an order), which builds the docs with -W and runs their examples (CI runs this, then make check)
	$(VENV)/bin/ruff check observers systems benchmarks tests
	$(PY) -m pytest -n $(TEST_JOBS) --dist worksteal --order-seed $(TEST_SEED)

docs: $(STAMP)  ## build the documentation site, warnings are errors -> docs/_build/html/index.html
	$(PY) -m sphinx -W --keep-going -b html docs docs/_build/html

lint: $(STAMP)  ## ruff only
	$(VENV)/bin/ruff check observers systems benchmarks tests

bench: $(STAMP)  ## incremental: run only the stale or missing rows of every published config (JOBS workers), merge them into results/<config>/, render reports/<config>.md and the HTML pages of the configs it ran, then every report drawn from several stores (fidelity.md)
	$(PY) -m benchmarks bench --jobs $(JOBS) --html
	$(PY) -m benchmarks reports
	$(PY) -m benchmarks index reports --committed
	$(PY) -m benchmarks index reports --results $(RESULTS)

bench-cold: $(STAMP)  ## every row of every published config from an empty design and floor cache (what the README times); HTML pages with figures: make report
	rm -rf $(RESULTS)/.cold-cache
	SETOBS_CACHE_DIR=$(abspath $(RESULTS))/.cold-cache $(PY) -m benchmarks designs $(CONFIGS_ALL) --jobs $(JOBS) --no-progress
	SETOBS_CACHE_DIR=$(abspath $(RESULTS))/.cold-cache $(PY) -m benchmarks bench --cold --jobs $(JOBS) --no-progress
	$(PY) -m benchmarks index reports --committed

reports: $(STAMP)  ## render every committed report from its result store and the dated block of every study and timing report, in seconds (no run; changes no byte when nothing changed)
	$(PY) -m benchmarks reports
	$(PY) -m benchmarks index reports --committed

stale: $(STAMP)  ## name the stored rows and committed reports a change made stale (no run; exit 1 if any), then the dated reports whose rows older code measured (no exit status)
	$(PY) -m benchmarks stale

speed: $(STAMP)  ## time the speed table -> reports/speed.md (compared with reports/speed.json), a dated report
	$(PY) -m benchmarks speed
	$(PY) -m benchmarks stale --record reports/speed.md

bench-quick: $(STAMP)  ## a small subset (about 1 min of CPU warm, 2 min on the first run): results/quick/run/index.html (HTML report) and report.md
	$(PY) -m benchmarks run $(CONFIGS_QUICK) --out $(RESULTS)/quick/run
	$(PY) -m benchmarks report $(RESULTS)/quick/run

scaling: $(STAMP)  ## scaling study, n-tank up to 200 states -> reports/scaling.md (budgeted)
	$(PY) -m benchmarks.studies.scaling --out reports/scaling.md --results $(RESULTS)/scaling
	$(PY) -m benchmarks stale --record reports/scaling.md

kernels: $(STAMP)  ## the paper tables re-run under every other OpenBLAS kernel of this CPU, each accuracy cell's spread against the committed stores -> reports/kernels.md, results/kernels/ (after make bench; only the rows whose stored fingerprint moved since run again)
	$(PY) -m benchmarks.studies.kernels --changed --jobs $(JOBS) --out reports/kernels.md --results $(RESULTS)
	$(PY) -m benchmarks stale --record reports/kernels.md
	$(PY) -m benchmarks reports
	$(PY) -m benchmarks index reports --committed

noise-grid: $(STAMP)  ## noise-level grid, gap and relative RMS against the scale of W, V, X0 on the 6-tank and the 6-D vehicle -> reports/noise_grid.md (JOBS workers)
	$(PY) -m benchmarks.studies.noise_grid --jobs $(JOBS) --out reports/noise_grid.md --results $(RESULTS)/noise_grid
	$(PY) -m benchmarks stale --record reports/noise_grid.md

robustness: $(STAMP)  ## rankings over the audit's realisations (20 per scenario, every guaranteed observer) -> reports/robustness.md (JOBS workers); only the observers whose code changed since it was measured run again
	$(PY) -m benchmarks.studies.robustness --changed --jobs $(JOBS) --out reports/robustness.md --results $(RESULTS)
	$(PY) -m benchmarks stale --record reports/robustness.md

frontier: $(STAMP)  ## frontier study, gap to the exact floor vs cost of the complexity knobs -> reports/frontier.md (budgeted)
	$(PY) -m benchmarks.studies.frontier --out reports/frontier.md --results $(RESULTS)/frontier
	$(PY) -m benchmarks stale --record reports/frontier.md

fidelity: $(STAMP)  ## the committed stores against the published tables (benchmarks/gate/fidelity.yaml; no run; exit 1 if a cell claimed within tolerance is not; part of make check)
	$(PY) -m benchmarks fidelity

check: $(STAMP)  ## CI gate: no stale stored row or report of the first tier (setobs-bench stale), every published cell claimed within tolerance is (fidelity), regression subset vs results/baseline/
	$(PY) -m benchmarks check --reports reports

baseline: $(STAMP)  ## rewrite the golden files in results/baseline/ (measures BLAS kernel sensitivity; commit them)
	$(PY) -m benchmarks baseline --update

datadriven: $(STAMP)  ## the data-driven study (Alanwar et al. 2022) -> reports/datadriven.md, and its fingerprint
	$(PY) -m benchmarks.studies.alanwar2022 --out reports/datadriven.md
	$(PY) -m benchmarks stale --record reports/datadriven.md

evidence: bench kernels audit datadriven speed scaling frontier noise-grid robustness  ## measure everything again: the stale rows, the audit, the data-driven study and the timing reports

BUMP ?= patch
release: bench  ## make bench, then measure again every dated report with a changed row (the studies, the audit, the timing reports), bump the version (BUMP=patch|minor|major) and tag it; the CHANGELOG entry lists what was re-measured
	@targets="$$($(PY) -m benchmarks release --plan)"; echo "release: re-measuring: $${targets:-nothing}"; \
		[ -z "$$targets" ] || $(MAKE) $$targets
	$(PY) -m benchmarks reports
	$(PY) -m benchmarks stale --all
	$(PY) -m benchmarks release --bump $(BUMP)

history: $(STAMP)  ## accuracy of the golden summaries over the git history -> results/history/index.html
	$(PY) -m benchmarks history

AUDIT_REALISATIONS ?= 20
audit: $(STAMP)  ## soundness audit (AUDIT_REALISATIONS per observer and scenario, default 20): only the stale pairs of results/soundness/ run; -> reports/soundness.md
	$(PY) -m benchmarks audit --realisations $(AUDIT_REALISATIONS)
	$(PY) -m benchmarks stale --record reports/soundness.md

AUDIT_SHORT_JOBS ?= 2
audit-short: $(STAMP)  ## CI: audit on 3 adversarial realisations per scenario (one per kind) -> results/audit-short/ (AUDIT_SHORT_JOBS workers, default 2)
	$(PY) -m benchmarks audit --short --no-progress --jobs $(AUDIT_SHORT_JOBS)

audit-edge: $(STAMP)  ## edge-case audit: every observer on the degenerate systems of systems/edge.py (short and long records) -> reports/edge_cases.md
	$(PY) -m benchmarks audit --edge --no-progress --jobs $(AUDIT_SHORT_JOBS)

audit-edge-short: $(STAMP)  ## CI: the edge-case audit on short records, one adversarial realisation -> results/edge-audit-short/
	$(PY) -m benchmarks audit --edge --short --no-progress --jobs $(AUDIT_SHORT_JOBS)

report: $(STAMP)  ## (re)write report.md, index.html and figures for every results/<config>/ (a store: figures of its last local run)
	@for dir in $(RESULTS)/*/; do \
		[ -f $$dir/summary.csv ] && $(PY) -m benchmarks report $$dir || true; \
	done

clean:  ## remove caches (keeps .venv and results)
	rm -rf .pytest_cache .ruff_cache build *.egg-info docs/_build docs/observers docs/api
