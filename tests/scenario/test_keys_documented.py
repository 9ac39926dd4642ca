"""Every key the scenario checker accepts is documented (docs/scenario.md is generated from the same
declarations): the checker is asked, through its own one-line error, which keys each mapping of the
file allows, and the answer must be the documented keys of that mapping, in their order."""
import copy
import re

import pytest

from wavecosim.errors import ConfigError
from wavecosim.scenario.config import key_reference, parse_scenario

BASE = {
    "dt": 0.01, "T": 0.1, "gamma": 0.4,
    "subsystems": {"A": {"fmu": "DuffingSide", "port": {}}, "B": {"fmu": "LinearSide"}},
    "couplings": [{"type": "equal_effort_opposite_flow", "ports": ["A", "B"]}],
    "master": {}, "certificates": {},
    "sources": {"S": {"csv": "s.csv"}},
    "signals": [{"from": "S.x", "to": "B.F"}],
}
UNKNOWN = "zz_not_a_key"
# the mapping of each documented section, as a path into BASE
WHERE = {"": (), "subsystems.NAME": ("subsystems", "A"), "subsystems.NAME.port": ("subsystems", "A", "port"),
         "couplings[i]": ("couplings", 0), "master": ("master",), "certificates": ("certificates",),
         "sources.NAME": ("sources", "S"), "signals[i]": ("signals", 0)}


def accepted(path, folder):
    """The keys the checker allows in the mapping at `path`, from its message about an unknown key."""
    (folder / "s.csv").write_text("time,x\n0.0,1.0\n")
    raw = copy.deepcopy(BASE)
    node = raw
    for part in path:
        node = node[part]
    node[UNKNOWN] = 1
    with pytest.raises(ConfigError) as exc:
        parse_scenario(raw, "keys.yaml", folder)
    found = re.search(rf"{re.escape(UNKNOWN)}: unknown key \(allowed: ([^)]*)\)", str(exc.value))
    assert found, str(exc.value)
    return found.group(1).split(", ")


SECTIONS = dict(key_reference())


@pytest.mark.parametrize("section", list(WHERE))
def test_the_checker_accepts_exactly_the_documented_keys(section, tmp_path):
    assert accepted(WHERE[section], tmp_path) == [row[0] for row in SECTIONS[section]]


def test_every_section_is_checked_and_every_key_has_a_meaning_and_type():
    assert set(SECTIONS) - set(WHERE) == {s for s in SECTIONS if s.startswith("an entry of")}
    for section, rows in SECTIONS.items():
        for key, kind, default, unit, meaning in rows:
            assert kind and default and meaning, (section, key)
