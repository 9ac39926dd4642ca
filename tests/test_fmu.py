"""master/fmu.py: safe extraction, errors that name the FMU and the variable, state handles freed."""
import zipfile

import pytest

from wavecosim.errors import FmuError
from wavecosim.fmu import Fmu, extract_fmu


def test_extraction_refuses_what_is_not_an_fmu(tmp_path):
    (tmp_path / "x.fmu").write_text("not a zip")
    with pytest.raises(FmuError, match="not an FMU"):
        extract_fmu(tmp_path / "x.fmu")
    with zipfile.ZipFile(tmp_path / "evil.fmu", "w") as z:
        z.writestr("modelDescription.xml", "<x/>")
        z.writestr("../evil", "x")
    with pytest.raises(FmuError, match="escapes the extraction folder"):
        extract_fmu(tmp_path / "evil.fmu")


def test_unknown_variable_names_the_fmu_and_the_variable(built_fmus):
    with pytest.raises(FmuError) as info:
        Fmu(built_fmus["LinearSide"], "B", {"no_such": 1.0})
    assert info.value.variable == "no_such" and "LinearSide.fmu has no variable 'no_such'" in str(info.value)


def test_status_error_names_subsystem_function_step_and_time(built_fmus):
    fmu = Fmu(built_fmus["LinearSide"], "B")
    try:
        err = fmu.status_error("fmi2DoStep", 3, step=5, time=0.05)
        assert str(err).startswith("subsystem B: fmi2DoStep returned Error at step 5 (t = 0.05): ")
        assert (err.subsystem, err.step) == ("B", 5)
    finally:
        fmu.close()


def test_refuses_non_finite_inputs(built_fmus):
    fmu = Fmu(built_fmus["LinearSide"], "B")
    try:
        with pytest.raises(FmuError, match="non-finite"):
            fmu.set_real(fmu.vrs(["a"]), [float("nan")])
    finally:
        fmu.close()
