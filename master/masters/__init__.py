"""Name-to-class table of masters, shared by YAML (`master.algorithm`) and the CLI (`--master`)."""
from .explicit import ExplicitMaster
from .fixed_point import GaussSeidelIterMaster, JacobiIterMaster
from .gauss_seidel import GaussSeidelMaster
from .newton import NewtonMaster
from .dr_fast import FastDRMaster  # DRMaster with the inner loop in C (master.fast), same numbers

MASTERS = {
    "dr": FastDRMaster,
    "newton": NewtonMaster,
    "explicit": ExplicitMaster,
    "gauss-seidel": GaussSeidelMaster,
    "jacobi-iter": JacobiIterMaster,
    "gauss-seidel-iter": GaussSeidelIterMaster,
}
