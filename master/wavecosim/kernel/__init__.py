"""Every binding of the C kernel (one place that knows its ABI) and its sources (c/), compiled into the
per-user cache on first use (build.py)."""
