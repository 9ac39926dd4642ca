"""Sequential explicit coupling: the second FMU already sees the first one's new output."""
from .explicit import ExplicitMaster


class GaussSeidelMaster(ExplicitMaster):
    """Like ExplicitMaster, but the subsystems step in the order the scenario lists them, each with
    inputs G y from the newest y."""
    style = ("tab:orange", "^")
    sequential = True
