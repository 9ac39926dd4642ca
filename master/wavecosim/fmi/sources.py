"""An FMU without a binary for this platform that ships its C sources (a source FMU, as OpenModelica
exports them beside a Windows binary): its binary is built once into the per-user cache, named by
the FMU's hash, and put where the FMU would have had it. With `sources/CMakeLists.txt` it is the
FMU's own CMake build (CMake from the `cmake` package fmpy depends on, else PATH); without, gcc over
the `<SourceFiles>` its interface lists, with the FMI headers fmpy ships."""
import hashlib
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from fmpy import sharedLibraryExtension

from ..errors import FmuError
from ..kernel.build import BuildError, fmi_headers, place, run, target

BUILD_TIMEOUT_S = 900


def provide_binary(path, folder, description, interface, platform):
    """Make folder/binaries/<platform>/<modelIdentifier> from the FMU's sources when it has no library
    for this platform and sources are there; nothing otherwise (check_runnable then says what is
    wrong, also a library there under another name)."""
    name = f"{interface.modelIdentifier}{sharedLibraryExtension}"
    binary = Path(folder) / "binaries" / platform / name
    sources = Path(folder) / "sources"
    if not sources.is_dir() or (binary.parent.is_dir() and any(binary.parent.glob(f"*{sharedLibraryExtension}"))):
        return
    key = hashlib.sha256(Path(path).read_bytes()).hexdigest()[:20]
    built = target("source-fmus", f"{key}-{platform}", name)
    if not built.exists():
        print(f"wavecosim: {Path(path).name} has no binary for {platform}; building it from its sources "
              f"(once, into {built.parent})", file=sys.stderr)
        try:
            place(lambda out: _build(sources, _source_files(description, interface), name, out), built)
        except BuildError as exc:
            raise FmuError(f"{Path(path).name} has no binary for this platform ({platform}) and its sources did "
                           f"not build: {str(exc).splitlines()[-1]}") from None
    binary.parent.mkdir(parents=True, exist_ok=True)
    shutil.copy2(built, binary)


def _source_files(description, interface):
    """The C files the FMU lists for its interface (FMI 2 <SourceFiles>, FMI 3 buildDescription.xml)."""
    return [f for config in description.buildConfigurations if config.modelIdentifier == interface.modelIdentifier
            for files in config.sourceFileSets for f in files.sourceFiles]


def _build(sources, listed, name, out):
    """Compile the sources into the shared library `out`."""
    with tempfile.TemporaryDirectory(prefix="wavecosim-source-fmu-") as tmp:
        if (sources / "CMakeLists.txt").exists():
            made = _cmake(sources, Path(tmp), name)
        else:
            files = [sources / f for f in listed]
            if not files:
                raise BuildError("the FMU lists no <SourceFiles> and has no sources/CMakeLists.txt")
            made = Path(tmp) / name
            run(["gcc", "-shared", "-fPIC", "-O2", f"-I{sources}", f"-I{fmi_headers()}", *files, "-o", made, "-lm"],
                name)
        shutil.copyfile(made, out)


def _cmake(sources, build, name):
    """The FMU's own CMake build; the library it makes."""
    cmake = _cmake_program()
    for cmd in ([cmake, "-S", sources, "-B", build, "-DCMAKE_BUILD_TYPE=Release"],
                [cmake, "--build", build, "--parallel", "2"]):
        try:
            proc = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, timeout=BUILD_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            raise BuildError(f"{' '.join(map(str, cmd))} took over {BUILD_TIMEOUT_S} s") from None
        if proc.returncode != 0:
            raise BuildError(f"{' '.join(map(str, cmd))}\n{(proc.stderr or proc.stdout).strip()}")
    found = sorted(build.rglob(name))
    if not found:
        raise BuildError(f"the CMake build made no {name}")
    return found[0]


def _cmake_program():
    try:
        import cmake
        program = Path(cmake.CMAKE_BIN_DIR) / "cmake"
        if program.exists():
            return program
    except ImportError:
        pass
    program = shutil.which("cmake")
    if program is None:
        raise BuildError("cmake was not found (pip install cmake)")
    return program
