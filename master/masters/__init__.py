"""Name-to-class table of masters, shared by YAML (`master.algorithm`) and the CLI (`--master`)."""
from .dr import DRMaster
from .newton import NewtonMaster

MASTERS = {
    "dr": DRMaster,
    "newton": NewtonMaster,
}
