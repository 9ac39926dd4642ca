# Two entry points; both set up .venv themselves (scripts/setup-venv.sh); the FMUs and the C kernel
# are built on demand into the per-user cache.
.PHONY: run test test-slow sweep bench setup

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

sweep: setup
	.venv/bin/wavecosim sweep --plots --out out/sweep

bench: setup
	.venv/bin/wavecosim bench
