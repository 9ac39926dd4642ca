"""Scenarios as plain, validated data: the YAML scenario file, SSP systems (ssp/), `--set` overrides.
Nothing here opens an FMU."""
