"""Name-to-class table of masters, shared by YAML (`master.algorithm`) and the CLI (`--master`)."""
from .dr import DRMaster
from .explicit import ExplicitMaster
from .fixed_point import GaussSeidelIterMaster, JacobiIterMaster
from .gauss_seidel import GaussSeidelMaster
from .newton import NewtonMaster

MASTERS = {
    "dr": DRMaster,
    "newton": NewtonMaster,
    "explicit": ExplicitMaster,
    "gauss-seidel": GaussSeidelMaster,
    "jacobi-iter": JacobiIterMaster,
    "gauss-seidel-iter": GaussSeidelIterMaster,
}
