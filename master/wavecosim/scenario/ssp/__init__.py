"""SSP in: `.ssd` files, `.ssp` archives and folders read as scenarios (README, "SSP in").

    import_ssp(path, ports=None, parameter_set=None) -> Imported (the scenario mapping, notes, origins)
    load_ssp(path, ...) -> (Scenario, Imported)
    write_draft(imported, out) writes the mapping as an editable YAML file with its origins as comments
"""
from .archive import is_ssp, ssp_only
from .importer import Imported, import_ssp, load_ssp

__all__ = ["is_ssp", "ssp_only", "import_ssp", "load_ssp", "Imported"]
