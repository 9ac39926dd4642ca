# Two entry points; both set up .venv themselves (scripts/setup-venv.sh) and build FMUs on demand.
.PHONY: run test sweep figures bench setup

setup:
	./scripts/setup-venv.sh

run: setup
	.venv/bin/wavecosim run --out out/run

test:
	./scripts/setup-venv.sh test
	.venv/bin/python -m pytest -q

sweep: setup
	.venv/bin/wavecosim sweep --plots --out out/sweep

bench: setup
	.venv/bin/wavecosim bench
