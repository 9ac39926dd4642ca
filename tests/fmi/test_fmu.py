"""wavecosim/fmi/fmu.py: safe extraction, errors that name the FMU and the variable, state handles freed."""
import re
import zipfile

import pytest

from paths import ROOT
from wavecosim.errors import FmuError
from wavecosim.cli import main
from wavecosim.fmi.fmu import Fmu, extract_fmu, interposed


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


def test_interposed_gives_the_hooks_pointers_within_the_block_only(built_fmus):
    """The seam a tool stands between the kernel and an FMU's functions through (the bench's floor)."""
    fmu = Fmu(built_fmus["LinearSide"], "B")
    seen = []

    def hook(name, component, fname, lookup):
        seen.append((name, component, fname))
        return 7 if fname == "fmi2DoStep" else lookup(fname)

    try:
        own = fmu.function_pointer("fmi2DoStep")
        with pytest.raises(KeyError):
            with interposed(hook):
                assert fmu.function_pointer("fmi2DoStep") == 7
                assert fmu.function_pointer("fmi2GetReal") != 7
                raise KeyError("the block fails")
        assert fmu.function_pointer("fmi2DoStep") == own
        assert seen == [("B", fmu.component, "fmi2DoStep"), ("B", fmu.component, "fmi2GetReal")]
    finally:
        fmu.close()


def test_refuses_non_finite_inputs(built_fmus):
    fmu = Fmu(built_fmus["LinearSide"], "B")
    try:
        with pytest.raises(FmuError, match="non-finite"):
            fmu.set_real(fmu.vrs(["a"]), [float("nan")])
    finally:
        fmu.close()


FEEDTHROUGH = ROOT.parent / "shared" / "third_party" / "reference_fmus" / "fmi2" / "Feedthrough.fmu"


@pytest.mark.skipif(not FEEDTHROUGH.exists(), reason="the third-party FMUs (../shared/third_party) are absent")
def test_values_of_every_fmi_type_are_set_with_their_declared_type():
    """The Reference FMU Feedthrough has Real, Integer, Boolean, String and Enumeration variables."""
    values = {"Float64_fixed_parameter": 2.5, "Int32_input": 7, "Boolean_input": True, "String_input": "hello",
              "Enumeration_input": 2}
    fmu = Fmu(FEEDTHROUGH, "ft", values)
    try:
        s, vr = fmu.slave, fmu.vr
        assert s.getReal([vr("Float64_fixed_parameter")]) == [2.5]
        assert s.getInteger([vr("Int32_input"), vr("Enumeration_input")]) == [7, 2]
        assert s.getBoolean([vr("Boolean_input")]) == [True]
        assert s.getString([vr("String_input")]) == [b"hello"]
    finally:
        fmu.close()
    with pytest.raises(FmuError, match="Boolean_input is a Boolean variable of Feedthrough.fmu; got 3"):
        Fmu(FEEDTHROUGH, "ft", {"Boolean_input": 3})


def test_an_integer_parameter_can_be_given_with_the_others(built_fmus):
    fmu = Fmu(built_fmus["DuffingSide"], "A", {"newton_max_iter": 7, "m1": 8})
    try:
        assert fmu.slave.getInteger([fmu.vr("newton_max_iter")]) == [7]
        assert fmu.get_real(fmu.vrs(["m1"])).tolist() == [8.0]
    finally:
        fmu.close()


def rewritten(source, target, rename=None, description=None, drop=None):
    """A copy of a built FMU with members renamed (rename: old prefix -> new), left out (drop: a
    prefix) or its modelDescription.xml changed (description: text -> text)."""
    with zipfile.ZipFile(source) as src, zipfile.ZipFile(target, "w") as dst:
        for item in src.infolist():
            data = src.read(item.filename)
            name = item.filename
            if drop and name.startswith(drop):
                continue
            if rename and name.startswith(rename[0]):
                name = rename[1] + name[len(rename[0]):]
            if description and name == "modelDescription.xml":
                data = data.decode().replace(*description).encode()
            dst.writestr(name, data)
    return target


@pytest.mark.parametrize("change, words", [
    ({"description": ('fmiVersion="2.0"', 'fmiVersion="1.0"')},
     "LinearSide.fmu is an FMI 1.0 FMU; wavecosim runs FMI 2.0 and 3.0 co-simulation FMUs"),
    ({"rename": ("binaries/linux64/", "binaries/win64/"), "drop": "sources/"},     # with sources it is built
     "LinearSide.fmu has no binary for this platform (linux64; it has: win64)"),
])
def test_an_fmu_this_build_cannot_run_is_one_line_and_exit_2(built_fmus, tmp_path, capsys, change, words):
    fmu = rewritten(built_fmus["LinearSide"], tmp_path / "LinearSide.fmu", **change)
    with pytest.raises(FmuError, match=re.escape(words)):
        Fmu(fmu, "B")
    scene = (ROOT / "configs" / "two_oscillators.yaml").read_text().replace("fmu: LinearSide", f"fmu: {fmu}")
    (tmp_path / "scene.yaml").write_text(scene)
    with pytest.raises(SystemExit) as info:
        main(["run", str(tmp_path / "scene.yaml"), "--out", str(tmp_path / "out"), "--quiet"])
    err = capsys.readouterr().err.strip().splitlines()
    assert info.value.code == 2 and len(err) == 1 and "subsystems.B.fmu: " in err[0] and words in err[0]
