"""The imported scenario as a YAML draft a user can edit: the scenario file format, with a comment
over each part saying where in the SSP system (or overlay) it came from."""
import math
import os
from pathlib import Path

import yaml

ORDER = ("name", "description", "start_time", "dt", "T", "gamma", "subsystems", "couplings", "sources", "signals", "master",
         "certificates", "outputs", "error", "fne_watch")
NEEDED = {"dt": "0.001"}


def _flow(value):
    """One value in YAML flow style on one line."""
    text = yaml.safe_dump(value, default_flow_style=True, width=math.inf, sort_keys=False)
    return text.removesuffix("\n...\n").strip()


def _comment(origins, key, indent=""):
    return [f"{indent}# from {origins[key]}"] if key in origins else []


def _fmu(value, folder):
    """A file path relative to the draft's folder (built-in names stay as they are)."""
    if not os.path.isabs(value):
        return value
    return os.path.relpath(value, folder)


def _subsystems(imported, folder):
    lines = ["subsystems:"]
    for name, sub in imported.raw["subsystems"].items():
        lines += _comment(imported.origins, f"subsystems.{name}", "  ") + [f"  {name}:"]
        lines.append(f"    fmu: {_flow(_fmu(sub['fmu'], folder))}")
        if "tolerance" in sub:
            lines += _comment(imported.origins, f"subsystems.{name}.tolerance", "    ")
            lines.append(f"    tolerance: {_flow(sub['tolerance'])}")
        if "parameters" in sub or "start" in sub:
            lines += _comment(imported.origins, f"subsystems.{name}.values", "    ")
        lines += [f"    {key}: {_flow(sub[key])}" for key in ("parameters", "start") if key in sub]
        if "port" in sub:
            lines += _comment(imported.origins, f"subsystems.{name}.port", "    ")
            lines.append(f"    port: {_flow(sub['port'])}")
        elif not any(name in c["ports"] for c in imported.raw["couplings"]):
            lines.append("    # no port: exchanges signals only")
    return lines


def draft_text(imported, folder) -> str:
    """The draft as text; `folder` is where it will be written (relative FMU paths)."""
    raw = imported.raw
    lines = [f"# Drafted by `wavecosim import-ssp` from {imported.ssd.name} ({imported.ssd.parent}).",
             "# Edit freely; every key is checked when the file is run (docs/scenario.md)."]
    lines += [f"# note: {note}" for note in imported.notes]
    for key in ORDER:
        if key == "subsystems":
            lines += _subsystems(imported, folder)
        elif key in ("couplings", "signals") and key in raw:
            lines += _comment(imported.origins, key) + [f"{key}:"] + [f"  - {_flow(item)}" for item in raw[key]]
            if key == "couplings" and not raw[key]:
                lines[-1] = ("couplings: []   # no power bond: the explicit master runs it; declare ports "
                             "with --ports for DR (docs/your-fmus.md)")
        elif key in raw:
            lines += _comment(imported.origins, key) + [f"{key}: {_flow(raw[key])}"]
        elif key in NEEDED:
            lines.append(f"# {key}: {NEEDED[key]}   # required: the SSD has no {key}; set it here")
    return "\n".join(lines) + "\n"


def write_draft(imported, out) -> Path:
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(draft_text(imported, out.parent.resolve()), encoding="utf-8")
    return out
