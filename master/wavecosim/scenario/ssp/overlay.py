"""What an SSD cannot say: the power ports and the run's settings (dt, gamma, master, ...), from
a YAML overlay (`--ports FILE`) or from our annotation on the SSD (type org.wavecosim.scenario)."""
from pathlib import Path

from ...errors import ConfigError
from .declarations import annotation, attributes
from .xmlfile import SSD, number, q

SCENARIO_ANNOTATION = "org.wavecosim.scenario"
SETTINGS = ("name", "description", "dt", "T", "gamma", "master", "certificates", "outputs", "error", "fne_watch")
OVERLAY_KEYS = ("ports", "tolerance", *SETTINGS)     # tolerance: every FMU's set-up tolerance


def read_overlay(path) -> dict:
    """The overlay's mapping, its keys checked (`ports` maps subsystem names to port mappings)."""
    from ..config import load_raw
    raw = load_raw(Path(path)) or {}
    if not isinstance(raw, dict):
        raise ConfigError(f"{path}: an overlay must be a mapping (keys: {', '.join(OVERLAY_KEYS)})")
    for key in raw:
        if key not in OVERLAY_KEYS:
            raise ConfigError(f"{path}: {key}: unknown key (allowed: {', '.join(OVERLAY_KEYS)})")
    ports = raw.get("ports") or {}
    if not isinstance(ports, dict) or not all(isinstance(p, dict) for p in ports.values()):
        raise ConfigError(f"{path}: ports: must map subsystem names to port mappings, got {ports!r}")
    return raw


def annotated_settings(path, root) -> dict:
    """Settings from <ssc:Annotation type="org.wavecosim.scenario"><wc:Scenario dt=.. gamma=..>
    with child elements wc:Master and wc:Certificates (attributes as YAML scalars), on the root or
    on its ssd:DefaultExperiment."""
    exp = root.find(q(SSD, "DefaultExperiment"))
    found = [annotation(path, owner, SCENARIO_ANNOTATION) for owner in (root, exp) if owner is not None]
    el = next((e for e in found if e is not None), None)
    if el is None:
        return {}
    settings = attributes(el, list_keys=("error",))
    for child in el:
        key = child.tag.split("}")[1].lower()
        settings[key] = attributes(child, list_keys=())
    if "error" in settings and not isinstance(settings["error"], list):
        settings["error"] = [settings["error"]]
    return settings


def experiment(path, root):
    """(startTime, stopTime) of ssd:DefaultExperiment, each None when not given."""
    exp = root.find(q(SSD, "DefaultExperiment"))
    if exp is None:
        return None, None
    return number(path, exp, "startTime", None), number(path, exp, "stopTime", None)
