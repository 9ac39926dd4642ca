"""SSP conformance on SSD files written here around the package's own FMUs (a point mass and a spring
that exchange force and velocity as signals), so a fresh clone tests what the third-party systems
exercise: a system without power bonds runs on the explicit master as a plain fmpy loop does;
connections to the system's own connectors (startElement="") and through nested systems both ways;
values through parameter and input connectors of systems; ssm:ParameterMapping (file and inline,
with its transformations); unit conversions; the time grid from the files; CSV time tables as
components; OMSimulator's signal filter."""
import re

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

import wavecosim as wc
from wavecosim.cli import main
from wavecosim.errors import ConfigError
from wavecosim.fmi.builtin import builtin_fmus
from wavecosim.scenario.ssp import import_ssp, load_ssp
from wavecosim.scenario.ssp.units import conversion

HEAD = ('<?xml version="1.0" encoding="UTF-8"?>\n<ssd:SystemStructureDescription version="{version}" name="{name}" '
        'xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription" '
        'xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon" '
        'xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" '
        'xmlns:ssm="http://ssp-standard.org/SSP1/SystemStructureParameterMapping" '
        'xmlns:oms="https://raw.githubusercontent.com/OpenModelica/OMSimulator/master/schema/oms.xsd">\n')
MASS = ('<ssd:Component name="mass" source="{mass}"><ssd:Connectors><ssd:Connector name="F" kind="input">'
        '<ssc:Real unit="N"/></ssd:Connector><ssd:Connector name="v" kind="output"><ssc:Real unit="m/s"/>'
        '</ssd:Connector><ssd:Connector name="x" kind="output"/><ssd:Connector name="m" kind="parameter"/>'
        '</ssd:Connectors>{bindings}</ssd:Component>')
SPRING = ('<ssd:Component name="spring" source="{spring}"><ssd:Connectors><ssd:Connector name="v" kind="input">'
          '<ssc:Real unit="m/s"/></ssd:Connector><ssd:Connector name="F" kind="output"><ssc:Real unit="N"/>'
          '</ssd:Connector><ssd:Connector name="x" kind="output"/><ssd:Connector name="k" kind="parameter"/>'
          '</ssd:Connectors>{bindings}</ssd:Component>')
PAIR = """<ssd:System name="top">
  <ssd:Connectors><ssd:Connector name="xm" kind="output"/><ssd:Connector name="xs" kind="output"/></ssd:Connectors>
  <ssd:Elements>{mass}{spring}</ssd:Elements>
  <ssd:Connections>
    <ssd:Connection startElement="spring" startConnector="F" endElement="mass" endConnector="F">{lt}</ssd:Connection>
    <ssd:Connection startElement="mass" startConnector="v" endElement="spring" endConnector="v"/>
    <ssd:Connection startElement="mass" startConnector="x" endElement="" endConnector="xm"/>
    <ssd:Connection startElement="spring" startConnector="x" endConnector="xs"/>
  </ssd:Connections>
</ssd:System>
"""
EXPERIMENT = '<ssd:DefaultExperiment startTime="0" stopTime="0.3"/>\n'
DT, STEPS = 0.01, 30


def fmus():
    return {"mass": builtin_fmus()["ForeignMass"], "spring": builtin_fmus()["ForeignSpring"]}


def write(folder, system, name="s.ssd", tail=EXPERIMENT, version="2.0", units=""):
    """An SSD around `system` (formatted with the FMUs' paths) in `folder`."""
    text = HEAD.format(version=version, name=name.split(".")[0]) + system + units + tail + \
        "</ssd:SystemStructureDescription>\n"
    path = folder / name
    path.write_text(text.replace("{mass}", str(fmus()["mass"])).replace("{spring}", str(fmus()["spring"])))
    return path


def pair(folder, lt="", mass_bindings="", spring_bindings="", **kw):
    system = PAIR.format(mass=MASS.format(mass="{mass}", bindings=mass_bindings),
                         spring=SPRING.format(spring="{spring}", bindings=spring_bindings), lt=lt)
    return write(folder, system, **kw)


def plain_loop(tmp_path, factor=1.0, offset=0.0, steps=STEPS):
    """The pair stepped by fmpy: at each t_n both outputs read, both inputs set, both doSteps."""
    out, slaves = [], {}
    for name, path in fmus().items():
        md = read_model_description(str(path))
        slave = FMU2Slave(guid=md.guid, unzipDirectory=extract(str(path), unzipdir=str(tmp_path / name)),
                          modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
        slave.instantiate()
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        slaves[name] = (slave, {v.name: v.valueReference for v in md.modelVariables})
    (mass, mv), (spring, sv) = slaves["mass"], slaves["spring"]
    for n in range(steps + 1):
        force, velocity = spring.getReal([sv["F"]])[0], mass.getReal([mv["v"]])[0]
        mass.setReal([mv["F"]], [factor * force + offset])
        spring.setReal([sv["v"]], [1.0 * velocity + 0.0])
        out.append((mass.getReal([mv["x"]])[0], spring.getReal([sv["x"]])[0]))
        if n < steps:
            mass.doStep(n * DT, DT)
            spring.doStep(n * DT, DT)
    for slave, _ in slaves.values():
        slave.terminate()
        slave.freeInstance()
    return np.array(out)


def simulate(scenario):
    return wc.simulate(scenario, reference=False, certificates=False).trajectory


def run_cli(capsys, *args):
    with pytest.raises(SystemExit) as exc:
        main([str(a) for a in args])
    captured = capsys.readouterr()
    return exc.value.code, captured.out, captured.err


# --- a system without power bonds ----------------------------------------------------------------

def test_a_signal_only_ssd_runs_with_no_flag_on_the_explicit_master_as_a_plain_loop(tmp_path, capsys, built_fmus):
    """The SSD alone: dt from the FMUs' DefaultExperiment, T from the SSD's, the explicit master,
    no gamma asked; the trajectory is a plain fmpy loop's to the last bit; an iterating master is
    refused in one line naming the reason."""
    path = pair(tmp_path, lt='<ssc:LinearTransformation factor="0.5" offset="0.25"/>')
    scenario, imported = load_ssp(path)
    assert (scenario.master.algorithm, scenario.gamma, scenario.couplings, scenario.dt) == ("explicit", None, [], DT)
    assert imported.origins["dt"] == "the DefaultExperiment stepSize of mass"
    got, expected = simulate(scenario), plain_loop(tmp_path, 0.5, 0.25)
    assert np.array_equal(got["xm"], expected[:, 0]) and np.array_equal(got["xs"], expected[:, 1])
    code, out, err = run_cli(capsys, "run", path, "--quiet", "--out", tmp_path / "out")
    assert code == 0 and "explicit" in out, err
    code, _, err = run_cli(capsys, "run", path, "--master", "dr", "--quiet", "--out", tmp_path / "dr")
    assert code == 2 and len(err.strip().splitlines()) == 1 and "dr couples power bonds" in err, err


# --- system connectors and nested systems ----------------------------------------------------------

NESTED = """<ssd:System name="top">
  <ssd:Connectors><ssd:Connector name="xm" kind="output"/></ssd:Connectors>
  <ssd:Elements>
    <ssd:System name="Outer">
      <ssd:Connectors><ssd:Connector name="Fin" kind="input"><ssc:Real unit="kN"/></ssd:Connector>
        <ssd:Connector name="vout" kind="output"><ssc:Real unit="mm/s"/></ssd:Connector>
        <ssd:Connector name="x" kind="output"/></ssd:Connectors>
      <ssd:Elements>
        <ssd:System name="Inner">
          <ssd:Connectors><ssd:Connector name="Fin" kind="input"><ssc:Real unit="N"/></ssd:Connector>
            <ssd:Connector name="vout" kind="output"><ssc:Real unit="m/s"/></ssd:Connector>
            <ssd:Connector name="x" kind="output"/></ssd:Connectors>
          <ssd:Elements>{mass}</ssd:Elements>
          <ssd:Connections>
            <ssd:Connection startElement="" startConnector="Fin" endElement="mass" endConnector="F">
              <ssc:LinearTransformation factor="0.5"/></ssd:Connection>
            <ssd:Connection startElement="mass" startConnector="v" endElement="" endConnector="vout"/>
            <ssd:Connection startElement="mass" startConnector="x" endConnector="x"/>
          </ssd:Connections>
        </ssd:System>
      </ssd:Elements>
      <ssd:Connections>
        <ssd:Connection startElement="" startConnector="Fin" endElement="Inner" endConnector="Fin"/>
        <ssd:Connection startElement="Inner" startConnector="vout" endElement="" endConnector="vout"/>
        <ssd:Connection startElement="Inner" startConnector="x" endElement="" endConnector="x"/>
      </ssd:Connections>
    </ssd:System>
    {spring}
  </ssd:Elements>
  <ssd:Connections>
    <ssd:Connection startElement="spring" startConnector="F" endElement="Outer" endConnector="Fin">
      <ssc:LinearTransformation offset="0.00025"/></ssd:Connection>
    <ssd:Connection startElement="Outer" startConnector="vout" endElement="spring" endConnector="v"/>
    <ssd:Connection startElement="Outer" startConnector="x" endElement="" endConnector="xm"/>
  </ssd:Connections>
</ssd:System>
"""
UNITS = """<ssd:Units>
  <ssc:Unit name="N"><ssc:BaseUnit kg="1" m="1" s="-2"/></ssc:Unit>
  <ssc:Unit name="kN"><ssc:BaseUnit kg="1" m="1" s="-2" factor="1000"/></ssc:Unit>
  <ssc:Unit name="m/s"><ssc:BaseUnit m="1" s="-1"/></ssc:Unit>
  <ssc:Unit name="mm/s"><ssc:BaseUnit m="1" s="-1" factor="0.001"/></ssc:Unit>
</ssd:Units>
"""


def test_nested_systems_both_ways_with_units_run_as_the_flat_pair(tmp_path, built_fmus):
    """spring.F (N) -> Outer.Fin (kN: x 1/1000, then offset 0.00025 kN) -> Inner.Fin (N: x 1000) ->
    mass.F (x 0.5): one signal 0.5 F + 0.125; mass.v (m/s) -> out of Inner, out of Outer (mm/s:
    x 1000) -> spring.v (m/s: x 1/1000): factor 1; the run equals the flat pair with that signal."""
    path = write(tmp_path, NESTED.format(mass=MASS.format(mass="{mass}", bindings=""),
                                         spring=SPRING.format(spring="{spring}", bindings="")), units=UNITS)
    raw = import_ssp(path).raw
    signals = {s["to"]: (s["from"], s["factor"], s["offset"]) for s in raw["signals"]}
    assert signals["mass.F"][0] == "spring.F" and signals["mass.F"][1] == 0.5
    assert signals["mass.F"][2] == pytest.approx(0.125, rel=1e-12)
    assert signals["spring.v"] == ("mass.v", 1.0, 0.0) and raw["outputs"] == {"xm": "mass.x"}
    flat = pair(tmp_path, lt=f'<ssc:LinearTransformation factor="0.5" offset="{signals["mass.F"][2]!r}"/>',
                name="flat.ssd")
    got, expected = simulate(load_ssp(path)[0]), simulate(load_ssp(flat)[0])
    assert np.array_equal(got["xm"], expected["xm"])


def test_unit_conversions_and_their_refusals(tmp_path, built_fmus):
    """degC -> K adds 273.15; a unit ssd:Units does not define, or of another quantity, is refused in
    one line naming the connection; suppressUnitConversion takes values as they are."""
    units = {"degC": ((0, 0, 0, 0, 1, 0, 0, 0), 1.0, 273.15), "K": ((0, 0, 0, 0, 1, 0, 0, 0), 1.0, 0.0)}
    from lxml import etree
    conn = etree.fromstring('<c suppressUnitConversion="false"/>')
    end = lambda unit: etree.fromstring(f'<c xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon">'
                                        f'<ssc:Real unit="{unit}"/></c>')             # noqa: E731
    assert conversion("x.ssd", conn, units, end("degC"), end("K")) == (1.0, 273.15)
    assert conversion("x.ssd", conn, units, end("K"), end("degC")) == (1.0, -273.15)
    conn.set("suppressUnitConversion", "true")
    assert conversion("x.ssd", conn, units, end("degC"), end("K")) == (1.0, 0.0)
    spring_v = '<ssd:Connector name="v" kind="input"><ssc:Real unit="m/s"/>'
    for unit, message in (("km/h", "connects unit 'm/s' to unit 'km/h', but ssd:Units does not define 'km/h'"),
                          ("N", "connects unit 'm/s' to unit 'N', which measure different quantities")):
        path = pair(tmp_path, name="bad.ssd", units=UNITS)
        path.write_text(path.read_text().replace(spring_v, spring_v.replace("m/s", unit)))
        line = next(i for i, t in enumerate(path.read_text().splitlines(), 1) if 'endConnector="v"' in t)
        with pytest.raises(ConfigError, match=rf"bad.ssd line {line}: <ssd:Connection .*: {re.escape(message)}"):
            import_ssp(path)


# --- values through system connectors, parameter mappings ------------------------------------------

SSV = """<?xml version="1.0" encoding="UTF-8"?>
<ssv:ParameterSet version="2.0" name="values" xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues">
<ssv:Parameters>{}</ssv:Parameters></ssv:ParameterSet>
"""
SSM = """<?xml version="1.0" encoding="UTF-8"?>
<ssm:ParameterMapping version="2.0" xmlns:ssm="http://ssp-standard.org/SSP1/SystemStructureParameterMapping"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon">{}</ssm:ParameterMapping>
"""
ENTRIES = ('<ssm:MappingEntry source="stiffness" target="spring.k"><ssc:LinearTransformation factor="4" offset="5"/>'
           '</ssm:MappingEntry><ssm:MappingEntry source="damping" target="spring.d"/>'
           '<ssm:MappingEntry source="damping" target="mass.c"/><ssm:MappingEntry source="" target="mass.m"/>'
           '<ssm:MappingEntry source="steps" target="mass.substeps"><ssc:IntegerMappingTransformation>'
           '<ssc:MapEntry source="3" target="5"/></ssc:IntegerMappingTransformation></ssm:MappingEntry>')


def real(name, value, kind="Real"):
    return f'<ssv:Parameter name="{name}"><ssv:{kind} value="{value}"/></ssv:Parameter>'


@pytest.mark.parametrize("where", ["file", "inline"])
def test_a_parameter_mapping_renames_and_transforms_the_bound_values(tmp_path, where, built_fmus):
    """stiffness 2 -> spring.k = 4 * 2 + 5 = 13; damping feeds two targets; steps 3 -> substeps 5
    by an integer map; an entry with an empty source maps nothing; x keeps its own name."""
    (tmp_path / "v.ssv").write_text(SSV.format(real("stiffness", 2.0) + real("damping", 0.125)
                                               + real("steps", 3, "Integer") + real("spring.x", 0.5)))
    (tmp_path / "m.ssm").write_text(SSM.format(ENTRIES))
    mapping = ('<ssd:ParameterMapping source="m.ssm"/>' if where == "file" else
               f'<ssd:ParameterMapping>{SSM.format(ENTRIES).split("?>", 1)[1]}</ssd:ParameterMapping>')
    system = PAIR.replace("  <ssd:Elements>", '<ssd:ParameterBindings>'
                          f'<ssd:ParameterBinding source="v.ssv">{mapping}</ssd:ParameterBinding>'
                          '</ssd:ParameterBindings><ssd:Elements>', 1)
    path = write(tmp_path, system.format(mass=MASS.format(mass="{mass}", bindings=""),
                                         spring=SPRING.format(spring="{spring}", bindings=""), lt=""))
    imported = import_ssp(path)
    subs = imported.raw["subsystems"]
    assert subs["spring"]["parameters"] == {"k": 13.0, "d": 0.125} and subs["spring"]["start"] == {"x": 0.5}
    assert subs["mass"]["parameters"] == {"c": 0.125, "substeps": 5} and imported.notes == []
    xs = simulate(load_ssp(path)[0])["xs"]
    assert xs[0] == 0.5 and xs[-1] != 0.5


SYSTEM_VALUES = """<ssd:System name="top">
  <ssd:Connectors><ssd:Connector name="k_sys" kind="parameter"><ssc:Real/></ssd:Connector>
    <ssd:Connector name="push" kind="input"><ssc:Real/></ssd:Connector>
    <ssd:Connector name="xm" kind="output"/><ssd:Connector name="ks" kind="output"/></ssd:Connectors>
  <ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues><ssv:ParameterSet version="2.0" name="p">
    <ssv:Parameters>{values}</ssv:Parameters></ssv:ParameterSet></ssd:ParameterValues></ssd:ParameterBinding>
  </ssd:ParameterBindings>
  <ssd:Elements>{mass}{spring}</ssd:Elements>
  <ssd:Connections>
    <ssd:Connection startElement="" startConnector="k_sys" endElement="spring" endConnector="k">
      <ssc:LinearTransformation factor="2"/></ssd:Connection>
    <ssd:Connection startElement="" startConnector="push" endElement="mass" endConnector="F"/>
    <ssd:Connection startElement="mass" startConnector="x" endElement="" endConnector="xm"/>
  </ssd:Connections>
</ssd:System>
"""


def test_parameter_and_input_connectors_of_the_system_pass_their_bound_values_on(tmp_path, built_fmus):
    """k_sys = 40 (a system parameter connector) -> spring.k = 2 x 40 = 80, over the spring's own
    binding k = 50; push = 0.25 (a system input nothing drives) -> mass.F's start value, so the mass
    accelerates at F/m from the start."""
    own = ('<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues><ssv:ParameterSet version="2.0" '
           f'name="p"><ssv:Parameters>{real("k", 50.0)}</ssv:Parameters></ssv:ParameterSet></ssd:ParameterValues>'
           '</ssd:ParameterBinding></ssd:ParameterBindings>')
    path = write(tmp_path, SYSTEM_VALUES.format(values=real("k_sys", 40.0) + real("push", 0.25),
                                                mass=MASS.format(mass="{mass}", bindings=""),
                                                spring=SPRING.format(spring="{spring}", bindings=own)))
    imported = import_ssp(path)
    subs = imported.raw["subsystems"]
    assert subs["spring"]["parameters"] == {"k": 80.0} and subs["mass"]["start"] == {"F": 0.25}
    assert "system connector k_sys" in imported.origins["subsystems.spring.values"]
    xm = simulate(load_ssp(path)[0])["xm"]
    assert xm[-1] == pytest.approx(0.5 * 0.25 * 0.3 ** 2, rel=1e-9)           # x = F t^2 / (2 m), m = 1


def test_a_parameter_driven_during_the_run_is_refused(tmp_path, built_fmus):
    system = PAIR.replace('<ssd:Connection startElement="mass" startConnector="v" endElement="spring" '
                          'endConnector="v"/>', '<ssd:Connection startElement="mass" startConnector="v" '
                          'endElement="spring" endConnector="k"/>')
    path = write(tmp_path, system.format(mass=MASS.format(mass="{mass}", bindings=""),
                                         spring=SPRING.format(spring="{spring}", bindings=""), lt=""))
    with pytest.raises(ConfigError, match=r"s.ssd line \d+: .*spring.k is a parameter, set before the run, but "
                                          r"mass.v gives values during it"):
        import_ssp(path)


# --- the time grid ---------------------------------------------------------------------------------

OSP = """<?xml version="1.0" encoding="utf-8"?>
<OspSystemStructure xmlns="http://opensimulationplatform.com/MSMI/OSPSystemStructure" version="0.1">
  <BaseStepSize>0.002</BaseStepSize></OspSystemStructure>
"""
OMS_STEP = ('<ssd:Annotations><ssc:Annotation type="org.openmodelica"><oms:Annotations><oms:SimulationInformation>'
            '<oms:FixedStepMaster description="oms-ma" stepSize="0.005"/></oms:SimulationInformation>'
            '</oms:Annotations></ssc:Annotation></ssd:Annotations></ssd:System>')


def test_the_step_size_comes_from_osp_then_omsimulator_then_the_fmus_and_the_stop_time_from_the_fmus(tmp_path,
                                                                                                    built_fmus):
    path = pair(tmp_path, tail="")                              # no DefaultExperiment: T from the FMUs'
    raw, origins = import_ssp(path).raw, import_ssp(path).origins
    assert (raw["dt"], raw["T"]) == (0.01, 10.0) and origins["T"] == "the DefaultExperiment stopTime of spring"
    path.write_text(path.read_text().replace("</ssd:System>", OMS_STEP, 1))
    assert import_ssp(path).raw["dt"] == 0.005
    (tmp_path / "OspSystemStructure.xml").write_text(OSP)
    imported = import_ssp(path)
    assert imported.raw["dt"] == 0.002 and imported.origins["dt"] == "BaseStepSize of OspSystemStructure.xml"
    assert import_ssp(path, settings={"dt": 0.001}).raw["dt"] == 0.001
    (tmp_path / "OspSystemStructure.xml").write_text(OSP.replace("0.002", "fast"))
    with pytest.raises(ConfigError, match=r"OspSystemStructure.xml line 3: .*BaseStepSize must be a positive number"):
        import_ssp(path)


# --- CSV time tables and the signal filter ---------------------------------------------------------

TABLE = """<ssd:System name="top">
  <ssd:Elements>{mass}
    <ssd:Component name="BC" type="application/table" source="bc.csv"/>
    <ssd:System name="Sub"><ssd:Connectors><ssd:Connector name="F" kind="output"/></ssd:Connectors></ssd:System>
  </ssd:Elements>
  <ssd:Connections>
    <ssd:Connection startElement="BC" startConnector="push" endElement="mass" endConnector="F"/>
  </ssd:Connections>
</ssd:System>
"""
FILTER = """<?xml version="1.0"?>
<oms:SignalFilter version="1.0">
  <oms:Variable name="tbl.top.mass.F" type="Real" kind="input" />
  <oms:Variable name="tbl.top.mass.x" type="Real" kind="output" />
  <oms:Variable name="tbl.top.mass.nothing" type="Real" kind="output" />
</oms:SignalFilter>
"""
FILTERED = ('<ssd:DefaultExperiment startTime="0" stopTime="0.3"><ssd:Annotations><ssc:Annotation '
            'type="org.openmodelica"><oms:Annotations><oms:SimulationInformation signalFilter="filter.xml"/>'
            '</oms:Annotations></ssc:Annotation></ssd:Annotations></ssd:DefaultExperiment>\n')


def test_a_csv_table_component_drives_inputs_and_the_signal_filter_names_what_is_recorded(tmp_path, built_fmus):
    """OMSimulator's table component (type application/table): its columns are outputs, linear in
    time (the input recorded at t_n+1 is the one held over the step from t_n); the signal filter file on the DefaultExperiment lists the recorded variables (model
    name.system name.component.variable), a name that matches nothing is noted."""
    (tmp_path / "bc.csv").write_text("time,push,other\n0,0,9\n0.1,1,9\n0.2,3,9\n0.3,3,9\n")
    (tmp_path / "filter.xml").write_text(FILTER)
    path = write(tmp_path, TABLE.format(mass=MASS.format(mass="{mass}", bindings="")), name="tbl.ssd", tail=FILTERED)
    scenario, imported = load_ssp(path)
    assert imported.raw["sources"] == {"BC": {"csv": str(tmp_path / "bc.csv"), "interpolation": "linear"}}
    assert imported.raw["outputs"] == {"mass.F": "mass.F", "mass.x": "mass.x"}
    assert any("filter.xml: not recorded" in n and "mass.nothing" in n for n in imported.notes)
    got = simulate(scenario)
    held = np.interp(got["time"], [0, 0.1, 0.2, 0.3], [0, 1, 3, 3])     # at t_n, held over the step to t_n+1
    assert np.allclose(got["mass.F"][1:], held[:-1], rtol=0, atol=1e-12) and got["mass.F"][0] == 0.0
    (tmp_path / "filter.xml").unlink()
    imported = import_ssp(path)
    assert "outputs" not in imported.raw and any("filter.xml is not there; recording without it" in n
                                                 for n in imported.notes)
    bad = path.read_text().replace('source="bc.csv"', 'source="bc.mat"')
    (tmp_path / "bc.mat").write_text("")
    (tmp_path / "bad.ssd").write_text(bad)
    with pytest.raises(ConfigError, match=r"bad.ssd line \d+: .*a table component reads CSV files, not bc.mat"):
        import_ssp(tmp_path / "bad.ssd")


def test_the_draft_of_a_signal_only_ssd_loads_as_the_same_scenario(tmp_path, capsys, built_fmus):
    path = pair(tmp_path, lt='<ssc:LinearTransformation factor="0.5"/>')
    code, _, err = run_cli(capsys, "import-ssp", path, "-o", tmp_path / "draft.yaml")
    assert code == 0, err
    text = (tmp_path / "draft.yaml").read_text()
    assert "# from the DefaultExperiment stepSize of mass" in text
    assert "couplings: []   # no power bond: the explicit master runs it" in text and "gamma" not in text
    ours = wc.load(tmp_path / "draft.yaml")
    theirs = load_ssp(path)[0]
    assert ours.signals == theirs.signals and ours.dt == theirs.dt and ours.master == theirs.master
