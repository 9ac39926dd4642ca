# Two entry points; both set up .venv themselves (scripts/setup-venv.sh); the FMUs and the C kernel
# are built on demand into the per-user cache.
.PHONY: run test test-slow test-cpu sweep bench setup docs figures

setup:
	./scripts/setup-venv.sh

run: setup
	.venv/bin/wavecosim run --out out/run

test:
	./scripts/setup-venv.sh test
	.venv/bin/python -m pytest -q

test-slow:
	./scripts/setup-venv.sh test
	.venv/bin/python -m pytest -q -m slow

# The arithmetic tests under each BLAS kernel this CPU can run (numpy's OpenBLAS picks one by CPU):
# the results must not depend on it.
test-cpu:
	./scripts/setup-venv.sh test
	./scripts/test-cpu-kernels.sh

sweep: setup
	.venv/bin/wavecosim sweep --plots --out out/sweep

bench: setup
	.venv/bin/wavecosim bench

# The documentation site into site/ (the docs extra: MkDocs, Material, mkdocstrings, mkdocs-click),
# its generated tables made first; --strict fails on a broken link, a page left out or a warning.
docs:
	./scripts/setup-venv.sh docs
	.venv/bin/python scripts/docs_tables.py
	NO_MKDOCS_2_WARNING=1 .venv/bin/python -m mkdocs build --strict --site-dir site

# Every figure of the README and the docs (docs/figures/*.png), from the shipped FMUs: the Table I
# sweep, the comparison of masters on Table I and the stiff scene (about 6 minutes), the scenes.
figures: setup
	.venv/bin/python scripts/make_figures.py
	.venv/bin/python scripts/pareto.py
	.venv/bin/python scripts/scene_figure.py
