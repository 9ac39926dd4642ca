"""A scenario made concrete: the scene of FMU subsystems, their ports and frozen port maps, signals,
the compiled interconnection, the wave formulas, certificates and the choice of gamma."""
