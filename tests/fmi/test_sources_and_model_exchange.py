"""FMUs as some tools ship them: without a binary for this platform but with their C sources (built
once into the cache, then used as if shipped), and with model exchange only (stepped as
co-simulation: CVode over each macro-step, events as fmpy's simulate_fmu handles them)."""
import re
import zipfile

import numpy as np
import pytest
from fmpy import simulate_fmu

import wavecosim as wc
from paths import THIRD_PARTY
from wavecosim.fmi.fmu import Fmu
from wavecosim.scenario.config import parse_scenario

REFERENCE = THIRD_PARTY / "reference_fmus" / "fmi2"
needs_reference = pytest.mark.skipif(not REFERENCE.exists(), reason="the Reference FMUs (../shared/third_party) are absent")


def copy_fmu(src, dst, drop=None, edit=None):
    """A copy of an FMU without the members whose names `drop` matches, modelDescription.xml through `edit`."""
    with zipfile.ZipFile(src) as z, zipfile.ZipFile(dst, "w") as out:
        for item in z.infolist():
            if drop and re.match(drop, item.filename):
                continue
            data = z.read(item)
            if edit and item.filename == "modelDescription.xml":
                data = edit(data.decode()).encode()
            out.writestr(item, data)
    return dst


def alone(path, T, dt, outputs):
    raw = {"name": "one", "dt": dt, "T": T, "subsystems": {"F": {"fmu": str(path)}},
           "outputs": {o: f"F.{o}" for o in outputs}}
    return wc.simulate(parse_scenario(raw, "one.yaml"), reference=False, certificates=False).trajectory


def test_an_fmu_without_a_binary_for_this_platform_is_built_from_its_sources_once(built_fmus, tmp_path, monkeypatch,
                                                                                   capfd):
    """Our ForeignMass without binaries/: gcc over its <SourceFiles> into the cache, told once on
    stderr; it then runs as the shipped binary does."""
    monkeypatch.setenv("WAVECOSIM_CACHE", str(tmp_path / "cache"))
    stripped = copy_fmu(built_fmus["ForeignMass"], tmp_path / "ForeignMass.fmu", drop=r"binaries/")
    for _ in range(2):
        fmu = Fmu(stripped, "mass", {"F": 2.0})
        fmu.close()
    err = capfd.readouterr().err
    assert err.count("ForeignMass.fmu has no binary for linux64; building it from its sources") == 1
    assert len(list((tmp_path / "cache" / "source-fmus").rglob("ForeignMass.so"))) == 1
    ours = alone(stripped, 0.2, 0.01, ["x", "v"])
    shipped = alone(built_fmus["ForeignMass"], 0.2, 0.01, ["x", "v"])
    assert np.allclose(ours["x"], shipped["x"], rtol=1e-12, atol=1e-15)


def test_sources_that_do_not_build_are_one_line(built_fmus, tmp_path, monkeypatch):
    monkeypatch.setenv("WAVECOSIM_CACHE", str(tmp_path / "cache"))
    broken = copy_fmu(built_fmus["ForeignMass"], tmp_path / "Broken.fmu", drop=r"binaries/|sources/model\.c")
    with pytest.raises(wc.FmuError, match=r"^Broken.fmu has no binary for this platform \(linux64; it has: none\), and "
                                          r"its sources did not build: .*model.c: No such file"):
        Fmu(broken, "broken")


def model_exchange_only(src, dst):
    """A copy of a Reference FMU that offers model exchange only."""
    return copy_fmu(src, dst, edit=lambda text: re.sub(r"<CoSimulation.*?</CoSimulation>", "", text, flags=re.S))


@needs_reference
@pytest.mark.parametrize("name, T, outputs", [("VanDerPol", 2.0, ["x0", "x1"]), ("BouncingBall", 3.0, ["h", "v"])])
def test_a_model_exchange_fmu_steps_as_fmpy_integrates_it(tmp_path, name, T, outputs):
    """Van der Pol (stiff-ish, smooth) and the bouncing ball (state events at every bounce): each
    macro-step integrated with CVode meets fmpy's own model-exchange simulation (CVode, one
    output per macro-step) to within the solvers' tolerance."""
    fmu = model_exchange_only(REFERENCE / f"{name}.fmu", tmp_path / f"{name}.fmu")
    ours = alone(fmu, T, 0.01, outputs)
    theirs = simulate_fmu(str(REFERENCE / f"{name}.fmu"), fmi_type="ModelExchange", stop_time=T, output_interval=0.01,
                          relative_tolerance=1e-4, output=outputs, record_events=False)
    assert len(ours) == len(theirs)
    for o in outputs:
        scale = np.max(np.abs(theirs[o]))
        assert np.max(np.abs(ours[o] - theirs[o])) < 2e-3 * scale, o
    if name == "BouncingBall":
        assert np.sum(np.diff(np.sign(ours["v"])) > 0) >= 2           # it bounced (v turns from - to +)
        assert ours["h"].min() > -1e-3


@needs_reference
def test_a_failing_model_exchange_step_is_an_fmu_error(tmp_path):
    fmu = model_exchange_only(REFERENCE / "VanDerPol.fmu", tmp_path / "VanDerPol.fmu")
    raw = {"name": "vdp", "dt": 0.01, "T": 0.1, "subsystems": {"F": {"fmu": str(fmu), "parameters": {"mu": 1e300}}}}
    with pytest.raises(wc.RunFailed) as exc:
        wc.simulate(parse_scenario(raw, "vdp.yaml"), reference=False, certificates=False)
    assert "model exchange step from t = " in str(exc.value) or "non-finite" in str(exc.value)


@needs_reference
def test_sources_whose_library_lacks_fmi_functions_are_refused_in_one_line(tmp_path, monkeypatch):
    """The FMI 3 Feedthrough's sources, compiled as its buildDescription.xml lists them, export none of
    the fmi3 functions (its own build adds what they need): refused, not cached, naming what is missing."""
    monkeypatch.setenv("WAVECOSIM_CACHE", str(tmp_path / "cache"))
    fmu = copy_fmu(THIRD_PARTY / "reference_fmus" / "fmi3" / "Feedthrough.fmu", tmp_path / "Feedthrough.fmu",
                   drop=r"binaries/")
    with pytest.raises(wc.FmuError, match=r"^Feedthrough.fmu has no binary for this platform \(x86_64-linux; it has: "
                                          r"none\), and its sources did not build: the library built from them lacks "
                                          r"fmi3\w+"):
        Fmu(fmu, "feedthrough")
    assert not list((tmp_path / "cache").rglob("Feedthrough.so"))


@needs_reference
def test_a_model_exchange_solver_is_set_up_below_the_tolerance_mode(tmp_path):
    """The solver of a model-exchange FMU is our CVode (1e-4 where nothing sets it): under a cap
    (master.fmu_tolerance, the tolerance mode's) it is set up at the cap, as any FMU with a solver."""
    path = model_exchange_only(REFERENCE / "VanDerPol.fmu", tmp_path / "VanDerPol.fmu")
    for at_most, told in ((None, None), (1e-6, 1e-6), (1e-2, 1e-4)):
        fmu = Fmu(path, "F", tolerance_at_most=at_most)
        try:
            assert fmu.tolerance == told and fmu._fmi.tolerance == (told or 1e-4)
        finally:
            fmu.close()
