"""MASTERS: the one list of masters, name -> class, used by YAML (`master.algorithm`), the CLI
(`--master`, `--masters`), `compare` (each class's `budgets`) and the plots (its `style`)."""
from .dr_fast import FastDRMaster  # DRMaster with the inner loop in C (master.fast), same numbers
from .explicit import ExplicitMaster
from .fixed_point import GaussSeidelIterMaster, JacobiIterMaster
from .gauss_seidel import GaussSeidelMaster
from .newton import NewtonMaster
from .quasi_newton import AitkenMaster, IQNILSMaster

MASTERS = {
    "explicit": ExplicitMaster,
    "gauss-seidel": GaussSeidelMaster,
    "jacobi-iter": JacobiIterMaster,
    "gauss-seidel-iter": GaussSeidelIterMaster,
    "aitken": AitkenMaster,
    "iqn-ils": IQNILSMaster,
    "newton": NewtonMaster,
    "dr": FastDRMaster,
}
ALGORITHMS = tuple(MASTERS)
