# membrane-contact: `make run` solves the built-in default case, `make test` runs every test
# (cargo test + make validate + the Python package's tests), `make python` builds the Python
# package into .venv/. Missing Debian packages are installed on first use: the solver's
# own for `make build` and `make run`, the dolfinx reference stack too for the tests.

SHELL := /bin/bash
PY := /usr/bin/python3
BIN := target/release/membrane-contact
# Link Debian's serial libhdf5 (its default pkg-config entry is the OpenMPI build).
export HDF5_DIR := /usr/lib/x86_64-linux-gnu/hdf5/serial
# What the solver needs to build and run (HDF5, and a font for the plots of study and adapt).
SOLVER_PACKAGES := libhdf5-dev pkg-config fonts-dejavu-core
# What the tests and the reference need beside it.
REFERENCE_PACKAGES := python3-dolfinx python3-petsc4py python3-meshio python3-h5py python3-paraview \
	python3-matplotlib python3-sympy python3-venv python3-pytest
# The Python package's virtual environment: Debian's python3 with its packages (dolfinx, numpy,
# meshio, h5py, pytest), and maturin from PyPI to build the wheel.
VENV := .venv
MATURIN ?= maturin>=1.5,<2
SUDO := $(shell [ "$$(id -u)" = 0 ] || echo sudo)
BENCH_SIZES ?= 256 512 1024 disk-6
# Multigrid only (Cholesky would not fit): 16.8M vertices, about 6 GB.
BENCH_LARGE ?= 4096
# Sizes also solved on one thread, for the speed-up of the threads.
BENCH_THREADS ?= 1024 4096
BENCH_REPEAT ?= 3
# Whole CLI runs (`solve --n N [options]`, spaces in the options as commas): wall time, peak memory
# and output size of the process, beside the phases it prints. 4096² takes minutes and about 6 GB.
BENCH_WHOLE ?= 1024 1024:--estimate 4096

.PHONY: all deps solver-deps build run test cargo-test validate python python-test bench bench-reference study fuzz lint mutants expr-property clean

all: build

deps: PACKAGES = $(SOLVER_PACKAGES) $(REFERENCE_PACKAGES)
solver-deps: PACKAGES = $(SOLVER_PACKAGES)
deps solver-deps:
	@missing=$$(for p in $(PACKAGES); do \
		dpkg-query -W -f='$${Status}\n' $$p 2>/dev/null | grep -q '^install ok installed' || echo $$p; done); \
	if [ -n "$$missing" ]; then \
		echo "installing Debian packages:" $$missing; \
		$(SUDO) apt-get update && DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y $$missing; \
	fi

build: solver-deps
	cargo build --release

run: build
	$(BIN) solve

test: cargo-test validate python-test

# The Python package membrane_contact (python/), built by maturin as an abi3 wheel and installed
# into .venv, made with --system-site-packages so that dolfinx and the package share one
# interpreter (Debian's python3 refuses a plain pip install).
python: deps
	[ -x $(VENV)/bin/python ] || $(PY) -m venv --system-site-packages $(VENV)
	$(VENV)/bin/python -m maturin --version >/dev/null 2>&1 || \
		$(VENV)/bin/python -m pip install --quiet "$(MATURIN)"
	rm -rf target/wheels
	$(VENV)/bin/python -m maturin build --release --strip --auditwheel skip -m python/Cargo.toml -i $(VENV)/bin/python
	$(VENV)/bin/python -m pip install --quiet --no-deps --force-reinstall target/wheels/membrane_contact-*.whl

python-test: python build
	$(VENV)/bin/python -m pytest python/tests -q

cargo-test: deps
	cargo test --release

validate: deps build
	$(PY) -m reference.validate --bin $(BIN) --out validation

bench: deps
	cargo build --release --benches --bins
	@{ for n in $(BENCH_SIZES); do for r in $$(seq $(BENCH_REPEAT)); do \
		for what in poisson poisson-mg contact contact-mg; do \
			cargo bench -q --bench phases -- $$what $$n | grep -E '^(poisson|contact)' ; \
		done; \
	done; done; \
	for n in $(BENCH_LARGE); do for r in $$(seq $(BENCH_REPEAT)); do \
		cargo bench -q --bench phases -- contact-mg $$n | grep '^contact' ; \
	done; done; \
	for n in $(BENCH_THREADS); do for r in $$(seq $(BENCH_REPEAT)); do \
		RAYON_NUM_THREADS=1 cargo bench -q --bench phases -- contact-mg $$n | sed -n 's/^contact-mg /contact-mg-1 /p' ; \
	done; done; \
	for spec in $(BENCH_WHOLE); do for r in $$(seq $(BENCH_REPEAT)); do \
		n=$${spec%%:*}; options=$$(echo "$${spec#$$n}" | tr ':,' '  '); \
		out=$$( { /usr/bin/time -f "wall=%e sys=%S peak_kb=%M" $(BIN) solve --quiet --n $$n $$options -o target/bench-whole; } 2>&1 ) \
			|| { echo "$$out" >&2; exit 1; }; \
		echo "whole $$spec bytes=$$(cat target/bench-whole/* | wc -c) $$(echo "$$out" | tr '\n' ' ')"; \
	done; done; } | tee target/bench.log | $(PY) -m reference.bench_table

bench-reference: deps build
	$(PY) -m reference.bench_reference --bin $(BIN)

# Convergence studies of the shipped exact cases (tables and plots under study/).
study: build
	$(BIN) study data/cases/default.toml --levels 8,16,32,64,128,256,512 --cold
	$(BIN) study data/cases/disk_jump.toml --levels 8,16,32,64,128,256
	$(BIN) study data/cases/lshape_corner.toml --levels 8,16,32,64,128,256 --grading 1,2
	$(BIN) study data/cases/disk_contact.toml --refine 0,1,2,3,4,5,6

FUZZ_SECONDS ?= 600
fuzz: deps
	command -v cargo-fuzz >/dev/null || cargo install cargo-fuzz
	cd fuzz && for t in case expr mesh xdmf; do \
		RUSTC_BOOTSTRAP=1 cargo fuzz run -O $$t -- -max_total_time=$(FUZZ_SECONDS) -max_len=4096 || exit 1; \
	done

# The random-expression property test with 200 000 expressions (make test runs 10 000).
expr-property: deps
	EXPR_CASES=200000 EXPR_SEED=2 cargo test --release --test expressions -- random_expressions

# Mutation testing of the numerical core (hours; not in CI): every mutant must fail a test, or be
# explained in docs/mutants.md. MUTANTS_FILES narrows it, e.g. MUTANTS_FILES=src/action.rs.
MUTANTS_FILES ?= src/assembly.rs 'src/contact/*.rs' src/action.rs src/flux.rs 'src/norms/*.rs' src/linear.rs 'src/estimator/*.rs'
mutants: deps
	command -v cargo-mutants >/dev/null || cargo install cargo-mutants --locked
	cargo mutants $(addprefix -f ,$(MUTANTS_FILES)) --profile mutants --timeout 300 --output target -- --lib --tests

lint:
	cargo fmt --all -- --check
	cargo clippy --all-targets -- -D warnings -W clippy::too_many_lines
	cargo clippy -p membrane-contact-python -- -D warnings
	RUSTDOCFLAGS="-D warnings" cargo doc --no-deps

clean:
	cargo clean
	rm -rf results validation $(VENV)
