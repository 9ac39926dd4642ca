"""metadata.json of a run: the scenario as resolved, the versions, the FMUs' checksums, the host."""
import dataclasses
import hashlib
import os
import platform
import sys
import time

_versions = {}


def _version(package):
    """The installed version of a package: its __version__ when it is imported, else its metadata
    (importlib.metadata costs about as much as a run of a few steps, so it is read only then); once."""
    if package not in _versions:
        found = getattr(sys.modules.get(package), "__version__", None)
        if not isinstance(found, str):
            from importlib import metadata as importlib_metadata
            try:
                found = importlib_metadata.version(package)
            except importlib_metadata.PackageNotFoundError:
                found = None
        _versions[package] = found
    return _versions[package]


def _sha256(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _scenario_record(scenario) -> dict:
    """The scenario as plain data, each time table named by its file, checksum and row count (its
    values can be hundreds of MB: they stay in the file)."""
    record = dataclasses.asdict(scenario)
    record["sources"] = [{"name": s.name, "csv": s.csv, "sha256": _sha256(s.csv), "interpolation": s.interpolation,
                          "rows": len(s.times), "columns": list(s.columns)} for s in scenario.sources]
    return record


def run_metadata(scenario, scene, units=None) -> dict:
    """Everything needed to tell two runs' set-ups apart (the scenario, software, FMU files, machine),
    and the unit of every recorded column."""
    return {
        "scenario": _scenario_record(scenario),
        "units": units or {},
        "gammas": dict(scene.gammas),
        "quirks": {name: dataclasses.asdict(d) for name, d in scene.decisions.items()},
        "versions": {"wavecosim": _version("wavecosim"), "python": sys.version.split()[0],
                     **{p: _version(p) for p in ("numpy", "scipy", "fmpy")}},
        "fmus": {s.name: {"path": str(s.fmu.path), "sha256": _sha256(s.fmu.path),
                          "fmiVersion": s.fmu.description.fmiVersion,
                          "guid": s.fmu.description.guid} for s in scene.subsystems + scene.signal_only},
        "host": {"node": platform.node(), "machine": platform.machine(), "system": platform.platform(),
                 "cpus": os.cpu_count()},
        "written": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
    }
