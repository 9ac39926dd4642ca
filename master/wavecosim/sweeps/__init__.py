"""Many runs: the budget sweep, general sweeps over scenario keys, the comparison of masters, and the
executors that run them (serial, a process pool, Dask)."""
