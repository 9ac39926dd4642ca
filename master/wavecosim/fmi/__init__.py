"""FMUs: the FMI 2 and FMI 3 co-simulation wrappers over fmpy, and the build of the package's own models."""
