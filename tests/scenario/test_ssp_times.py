"""Every file's times: an SSD's step, start and stop time from its DefaultExperiment, libcosim's OSP
annotation (`osp:FixedStepAlgorithm baseStepSize startTime stopTime`), OSP-IS
(OspSystemStructure.xml beside it), then the FMUs' DefaultExperiment, the command line over all;
summary.json (`times_from`) and the run's first line say where each came from. SSD files written
here around the package's Gain FMU (its DefaultExperiment: step 0.1, stop 1)."""
import json

import numpy as np
import pytest

import wavecosim as wc
from wavecosim.cli import main
from wavecosim.errors import ConfigError
from wavecosim.fmi.builtin import builtin_fmus
from wavecosim.scenario.ssp import import_ssp

SSD = """<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription version="1.0" name="times"
    xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"
    xmlns:osp="http://opensimulationplatform.com/SSP/OSPAnnotations">
  <ssd:System name="top">
    <ssd:Elements>
      <ssd:Component name="A" source="{gain}"><ssd:Connectors>
        <ssd:Connector name="u" kind="input"/><ssd:Connector name="y" kind="output"/></ssd:Connectors></ssd:Component>
      <ssd:Component name="B" source="{gain}"><ssd:Connectors>
        <ssd:Connector name="u" kind="input"/><ssd:Connector name="y" kind="output"/></ssd:Connectors></ssd:Component>
    </ssd:Elements>
    <ssd:Connections>
      <ssd:Connection startElement="A" startConnector="y" endElement="B" endConnector="u"/>
    </ssd:Connections>
  </ssd:System>
  {experiment}
</ssd:SystemStructureDescription>
"""
OSP_ANNOTATION = """<ssd:DefaultExperiment{attributes}><ssd:Annotations>
    <ssc:Annotation type="com.opensimulationplatform"><osp:Algorithm>
      <osp:FixedStepAlgorithm baseStepSize="{step}"{times}/>
    </osp:Algorithm></ssc:Annotation></ssd:Annotations></ssd:DefaultExperiment>"""
OSP_IS = """<?xml version="1.0" encoding="utf-8"?>
<OspSystemStructure xmlns="http://opensimulationplatform.com/MSMI/OSPSystemStructure" version="0.1">
  <StartTime>{start}</StartTime><BaseStepSize>{step}</BaseStepSize><StopTime>{stop}</StopTime>
</OspSystemStructure>
"""


def ssd(folder, experiment=""):
    path = folder / "SystemStructure.ssd"
    path.write_text(SSD.format(gain=builtin_fmus()["Gain"], experiment=experiment))
    return path


def annotated(folder, step="0.025", times=' startTime="0" stopTime="0.2"', attributes=""):
    return ssd(folder, OSP_ANNOTATION.format(step=step, times=times, attributes=attributes))


def run_cli(capsys, *args):
    with pytest.raises(SystemExit) as exc:
        main([str(a) for a in args])
    captured = capsys.readouterr()
    return exc.value.code, captured.out, captured.err


def test_the_osp_annotation_gives_the_step_start_and_stop(tmp_path, capsys):
    path = annotated(tmp_path)
    code, out, err = run_cli(capsys, "run", path, "--quiet", "--out", tmp_path / "out")
    assert code == 0, err
    origin = "SSD annotation osp:FixedStepAlgorithm"
    assert f"dt=0.025 ({origin} baseStepSize (SystemStructure.ssd line 19))" in out.splitlines()[0]
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert (summary["dt"], summary["start_time"], summary["T"], summary["steps"]) == (0.025, 0.0, 0.2, 8)
    assert summary["times_from"] == {key: f"{origin} {attribute} (SystemStructure.ssd line 19)" for key, attribute in
                                     (("dt", "baseStepSize"), ("start_time", "startTime"), ("T", "stopTime"))}
    times = np.genfromtxt(tmp_path / "out" / "trajectory.csv", delimiter=",", names=True)["time"]
    assert np.allclose(np.diff(times), 0.025) and len(times) == 9
    metadata = json.loads((tmp_path / "out" / "metadata.json").read_text())
    assert metadata["scenario"]["times_from"] == summary["times_from"]


def test_the_command_line_overrides_the_annotation(tmp_path, capsys):
    path = annotated(tmp_path)
    code, out, err = run_cli(capsys, "run", path, "--dt", "0.05", "--quiet", "--out", tmp_path / "out")
    assert code == 0, err
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert (summary["dt"], summary["steps"], summary["times_from"]["dt"]) == (0.05, 4, "the command line")
    assert summary["times_from"]["T"].startswith("SSD annotation osp:FixedStepAlgorithm stopTime")
    assert "dt=0.05 (the command line)" in out.splitlines()[0]


def test_precedence_default_experiment_annotation_osp_is_fmus(tmp_path):
    """The SSD's DefaultExperiment over the annotation over OSP-IS over the FMUs, key by key."""
    (tmp_path / "OspSystemStructure.xml").write_text(OSP_IS.format(start=0.5, step=0.05, stop=0.9))
    path = annotated(tmp_path, times=' stopTime="0.7"', attributes=' stopTime="0.6"')
    scenario = wc.load(path)
    assert (scenario.start_time, scenario.dt, scenario.T) == (0.5, 0.025, 0.6)
    assert scenario.times_from == {"start_time": "StartTime of OspSystemStructure.xml",
                                   "dt": "SSD annotation osp:FixedStepAlgorithm baseStepSize (SystemStructure.ssd "
                                         "line 19)", "T": "ssd:DefaultExperiment stopTime"}
    path = ssd(tmp_path)
    scenario = wc.load(path)
    assert (scenario.start_time, scenario.dt, scenario.T) == (0.5, 0.05, 0.9)
    assert scenario.times_from["dt"] == "BaseStepSize of OspSystemStructure.xml"
    assert scenario.times_from["T"] == "StopTime of OspSystemStructure.xml"
    (tmp_path / "OspSystemStructure.xml").unlink()
    scenario = wc.load(path)
    assert (scenario.start_time, scenario.dt, scenario.T) == (0.0, 0.1, 1.0)
    assert scenario.times_from == {"start_time": "the DefaultExperiment startTime of B",
                                   "dt": "the DefaultExperiment stepSize of A", "T": "the DefaultExperiment stopTime of B"}


def test_a_bad_annotation_is_refused_naming_its_line(tmp_path):
    with pytest.raises(ConfigError, match=r"SystemStructure.ssd line 19: .*baseStepSize must be a positive number"):
        import_ssp(annotated(tmp_path, step="-1"))
    (tmp_path / "OspSystemStructure.xml").write_text(OSP_IS.format(start="soon", step=0.05, stop=0.9))
    with pytest.raises(ConfigError, match=r"OspSystemStructure.xml line 3: .*StartTime must be a number"):
        import_ssp(ssd(tmp_path))


def test_a_scenario_file_says_where_its_times_came_from(built_fmus):
    raw = {"subsystems": {"A": {"fmu": "Gain"}}}
    scenario = wc.api.with_overrides(wc.scenario.config.parse_scenario(raw, "g.yaml", settings={"T": 0.5}), dt=0.05)
    assert scenario.times_from == {"start_time": "the DefaultExperiment startTime of A", "dt": "the command line",
                                   "T": "the command line"}
    assert scenario.times_line() == ("dt=0.05 (the command line) start=0.0 (the DefaultExperiment startTime of A) "
                                     "T=0.5 (the command line)")
