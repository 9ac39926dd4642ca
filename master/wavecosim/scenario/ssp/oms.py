"""What OMSimulator writes into an SSD for itself (annotation type org.openmodelica): the fixed step
of its master on the top system (`oms:FixedStepMaster stepSize`) and, on ssd:DefaultExperiment, the
signal filter file that lists the variables its result file records (`oms:SimulationInformation
signalFilter`, a list of `oms:Variable name="model.system.element.variable"`)."""
from lxml import etree

from ...errors import ConfigError
from .xmlfile import SSC, SSD, number, q

OMS = "https://raw.githubusercontent.com/OpenModelica/OMSimulator/master/schema/oms.xsd"
ANNOTATION = "org.openmodelica"


def _information(owner):
    """The oms:SimulationInformation elements in `owner`'s org.openmodelica annotations."""
    holder = None if owner is None else owner.find(q(SSD, "Annotations"))
    found = []
    for note in [] if holder is None else holder.findall(q(SSC, "Annotation")):
        if note.get("type") == ANNOTATION:
            found += list(note.iter(q(OMS, "SimulationInformation")))
    return found


def fixed_step(path, root):
    """(stepSize, the element) of OMSimulator's fixed-step master on the top system, or (None, None)."""
    for info in _information(root.find(q(SSD, "System"))):
        master = info.find(q(OMS, "FixedStepMaster"))
        if master is not None and master.get("stepSize") is not None:
            return number(path, master, "stepSize", None), master
    return None, None


def signal_filter(path, root):
    """The signal filter file named on ssd:DefaultExperiment (resolved against the SSD), or None."""
    for info in _information(root.find(q(SSD, "DefaultExperiment"))):
        if info.get("signalFilter"):
            return (path.parent / info.get("signalFilter")).resolve()
    return None


def filtered_names(filter_path, prefix):
    """The names of the variables a signal filter file lists, without `prefix` (model.system.), in
    their order; names outside the prefix are left out. OMSimulator writes the oms: prefix without
    declaring its namespace, so the file is read leniently (its element names, prefix and all)."""
    try:
        tree = etree.parse(str(filter_path), etree.XMLParser(recover=True))
    except OSError as exc:
        raise ConfigError(f"{filter_path}: cannot read the signal filter: {exc}") from None
    root = tree.getroot()
    if root is None:
        raise ConfigError(f"{filter_path.name}: not a signal filter (no XML element)")
    names = [el.get("name", "") for el in root.iter() if isinstance(el.tag, str)
             and el.tag.rsplit("}", 1)[-1].rsplit(":", 1)[-1] == "Variable"]
    return [n[len(prefix):] for n in names if n.startswith(prefix)]
