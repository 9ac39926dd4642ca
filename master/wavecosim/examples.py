"""The example scenarios shipped inside the package (`wavecosim examples` lists them), loadable by
name from any folder:

    wc.simulate("two_oscillators", K=5)          # or wc.simulate(wavecosim.examples.path("two_oscillators"))

DEFAULT is the scene `wavecosim run` runs without a CONFIG: the paper's benchmark (Table I).
"""
import os
import re
from pathlib import Path

import yaml

CONFIGS = (Path(__file__).resolve().parent / "data" / "configs").resolve()
DEFAULT = CONFIGS / "two_oscillators.yaml"


def names():
    """The example scenarios' names (scenario files and SSP systems), sorted."""
    return sorted(p.stem if p.suffix == ".yaml" else p.name for p in CONFIGS.iterdir()
                  if p.suffix in (".yaml", ".ssd"))


def path(name) -> Path:
    """The file of an example scenario: `two_oscillators`, `two_oscillators.yaml` or `two_oscillators.ssd`."""
    found = CONFIGS / name if Path(name).suffix else CONFIGS / f"{name}.yaml"
    if not found.is_file():
        raise FileNotFoundError(f"no example scenario {name!r}; the examples are: {', '.join(names())}")
    return found


def resolve(given):
    """`given` as it is, or the example it names when it is a bare name of no file here
    (`two_oscillators`, `two_oscillators.ssd`): how a scenario is found by name from any folder."""
    if given is None or Path(given).exists() or len(Path(given).parts) != 1:
        return given
    try:
        return path(str(given))
    except FileNotFoundError:
        return given


def third_party():
    """The folder of third-party FMUs and systems some examples use ($WAVECOSIM_THIRD_PARTY, else
    ../shared/third_party beside a source checkout), or None when it is absent."""
    folder = Path(os.environ.get("WAVECOSIM_THIRD_PARTY") or CONFIGS.parent.parent / "shared" / "third_party")
    return folder if folder.is_dir() else None


def describe(name) -> dict:
    """{name, description, needs}: an example's one-line description (its `description:`, else the SSD's
    system description, else its first comment line) and what it needs to run here ("" when nothing)."""
    file = path(name)
    text = file.read_text(encoding="utf-8")
    if file.suffix == ".ssd":
        found = re.search(r'<ssd:System\b[^>]*\bdescription="([^"]*)"', text)
        return {"name": name, "description": found.group(1) if found else "", "needs": ""}
    raw = yaml.safe_load(text) or {}
    comment = next((ln.lstrip("# ").strip() for ln in text.splitlines() if ln.startswith("#")), "")
    return {"name": name, "description": str(raw.get("description") or comment), "needs": _needs(raw)}


def _needs(raw):
    """What a scenario mapping needs that is not here: FMU files its paths name, or (an overlay) an SSP system."""
    if "ports" in raw and "subsystems" not in raw:
        return "an SSP system: it is a --ports overlay, not a scenario (wavecosim run System.ssd --ports FILE)"
    subsystems = raw.get("subsystems") or {}
    missing = sorted({str(s["fmu"]) for s in subsystems.values() if isinstance(s, dict)
                      and str(s.get("fmu", "")).endswith(".fmu") and not (CONFIGS / s["fmu"]).resolve().is_file()})
    folders = {}
    for fmu in missing:
        folders.setdefault(str(Path(fmu).parent), []).append(Path(fmu).name)
    return "; ".join(f"{', '.join(files)} in {folder}" for folder, files in folders.items()) + (
        " (FMUs not installed with the package)" if missing else "")
