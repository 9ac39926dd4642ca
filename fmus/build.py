"""Build every model in models/ into an FMI 2.0 co-simulation FMU, and the C helper libraries.

One loop: for each models/<name>/, compile the shared FMI layer with the model into
binaries/linux64/<Id>.so, print modelDescription.xml from the same tables, zip into
build/fmus/<Id>.fmu. A build is skipped when a stamp of the sources and flags is unchanged.

    python fmus/build.py [--force]
"""
import hashlib
import importlib.util
import os
import re
import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
LAYER = ROOT / "fmus" / "layer"
KERNEL = ROOT / "fmus" / "kernel"
MODELS = ROOT / "models"
SPECS = ROOT / "specs"
GEN = ROOT / "build" / "gen"
CODEGEN = ROOT / "fmus" / "codegen"
OUT = ROOT / "build" / "fmus"
LIB_OUT = ROOT / "build" / "lib"
CFLAGS = ["-O2", "-std=c99", "-fPIC", "-ffp-contract=off", "-Wall", "-Wextra", "-Werror"]
PLATFORM = "linux64"


class BuildError(RuntimeError):
    """A model or helper library failed to compile."""


def fmi_headers() -> Path:
    """The official FMI 2.0 headers shipped inside fmpy."""
    import fmpy
    return Path(fmpy.__file__).parent / "c-code"


def _run(cmd, what):
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        raise BuildError(f"building {what} failed: {' '.join(map(str, cmd))}\n{proc.stderr.strip()}")
    return proc.stdout


def _stamp(files, extra=""):
    h = hashlib.sha256(" ".join(CFLAGS).encode() + extra.encode())
    for f in sorted(files):
        h.update(str(f.relative_to(ROOT)).encode())
        h.update(f.read_bytes())
    return h.hexdigest()


def _sources(model_dir: Path):
    return [p for p in LAYER.iterdir() if p.suffix in (".c", ".h")] + \
           [p for p in model_dir.iterdir() if p.suffix in (".c", ".h")]


def _packed_sources(model_dir: Path):
    """What goes into the FMU's sources/: the binary's C files (the <SourceFiles> that describe.c
    lists) and the headers they include; describe.c is a build tool, not part of the model."""
    return [p for p in _sources(model_dir) if p.name != "describe.c"]


def model_identifier(model_dir: Path) -> str:
    text = (model_dir / "config.h").read_text()
    m = re.search(r"#define\s+MODEL_IDENTIFIER\s+(\w+)", text)
    if not m:
        raise BuildError(f"{model_dir / 'config.h'}: no MODEL_IDENTIFIER")
    return m.group(1)


def build_model(model_dir: Path, force=False, log=print) -> Path:
    """Compile one model into build/fmus/<Id>.fmu; returns its path."""
    ident = model_identifier(model_dir)
    target = OUT / f"{ident}.fmu"
    stamp_file = OUT / f"{ident}.stamp"
    stamp = _stamp(_sources(model_dir))
    if not force and target.exists() and stamp_file.exists() and stamp_file.read_text() == stamp:
        return target
    log(f"building {target.relative_to(ROOT)}")
    OUT.mkdir(parents=True, exist_ok=True)
    includes = ["-I", str(fmi_headers()), "-I", str(LAYER), "-I", str(model_dir)]
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        describe = tmp / "describe"
        _run(["gcc", *CFLAGS, *includes, str(LAYER / "describe.c"), "-o", str(describe)], f"{ident} description")
        xml = _run([str(describe)], f"{ident} description")
        bindir = tmp / "binaries" / PLATFORM
        bindir.mkdir(parents=True)
        _run(["gcc", *CFLAGS, "-shared", *includes, str(LAYER / "fmi2_cosim.c"), str(model_dir / "model.c"),
              "-o", str(bindir / f"{ident}.so"), "-lm"], ident)
        part = target.with_suffix(".fmu.part")
        with zipfile.ZipFile(part, "w", zipfile.ZIP_DEFLATED) as z:
            z.writestr("modelDescription.xml", xml)
            z.write(bindir / f"{ident}.so", f"binaries/{PLATFORM}/{ident}.so")
            for src in _packed_sources(model_dir):
                z.write(src, f"sources/{src.name}")
        os.replace(part, target)
    stamp_file.write_text(stamp)
    return target


def build_library(name: str, sources, force=False, log=print) -> Path:
    """Compile C helper sources (fmus/kernel) into build/lib/lib<name>.so."""
    target = LIB_OUT / f"lib{name}.so"
    stamp_file = LIB_OUT / f"lib{name}.stamp"
    stamp = _stamp(sources)
    if not force and target.exists() and stamp_file.exists() and stamp_file.read_text() == stamp:
        return target
    log(f"building {target.relative_to(ROOT)}")
    LIB_OUT.mkdir(parents=True, exist_ok=True)
    part = target.with_suffix(".part.so")
    _run(["gcc", *CFLAGS, "-shared", "-I", str(fmi_headers()), *[str(s) for s in sources if s.suffix == ".c"],
          "-o", str(part), "-lm", "-ldl"], name)
    os.replace(part, target)
    stamp_file.write_text(stamp)
    return target


def model_dirs():
    return sorted(p for p in MODELS.iterdir() if (p / "config.h").exists())


def build_spec(spec: Path, force=False, log=print) -> Path:
    """Generate build/gen/<name>/ from a port-Hamiltonian spec (fmus/codegen/ph.py), then build it
    as a model; generation is skipped while the spec and the generator are unchanged."""
    out = GEN / spec.stem
    stamp = _stamp([spec, *CODEGEN.glob("*.py"), *CODEGEN.glob("*.h")])
    stamp_file = out / "spec.stamp"
    if force or not (out / "config.h").exists() or not stamp_file.exists() or stamp_file.read_text() != stamp:
        codegen().generate(spec, out)
        stamp_file.write_text(stamp)
    return build_model(out, force, log)


def codegen():
    """fmus/codegen/ph.py loaded as a module (a sibling script folder, not a package)."""
    loader = importlib.util.spec_from_file_location("wavecosim_codegen_ph", CODEGEN / "ph.py")
    ph = importlib.util.module_from_spec(loader)
    loader.loader.exec_module(ph)
    return ph


def spec_files():
    return sorted(SPECS.glob("*.yaml")) if SPECS.is_dir() else []


def build_all(force=False, log=print) -> dict:
    """Build every model (and the kernel library if present); returns {identifier: fmu path}."""
    if shutil.which("gcc") is None:
        raise BuildError("gcc was not found on PATH; it is needed to build the FMUs")
    fmus = {model_identifier(d): build_model(d, force, log) for d in model_dirs()}
    for spec in spec_files():
        path = build_spec(spec, force, log)
        fmus[model_identifier(GEN / spec.stem)] = path
    if KERNEL.is_dir():
        for c_file in sorted(KERNEL.glob("*.c")):
            if c_file.name not in PART_OF_LIBRARY:
                kernel_library(c_file.stem, force, log)
    return fmus


# C files compiled into another file's library: the routes built on the DR kernel's subsystem
# evaluation (classical.c, newton.c, certs.c) go into libdrkernel.so.
PART_OF_LIBRARY = {"classical.c": "drkernel", "newton.c": "drkernel", "certs.c": "drkernel"}


def kernel_library(name: str, force=False, log=print) -> Path:
    """build/lib/lib<name>.so from fmus/kernel/<name>.c and the files PART_OF_LIBRARY puts in it
    (with the kernel's headers)."""
    parts = sorted(KERNEL / f for f, lib in PART_OF_LIBRARY.items() if lib == name)
    return build_library(name, [KERNEL / f"{name}.c", *parts, *sorted(KERNEL.glob("*.h"))], force, log)


if __name__ == "__main__":
    try:
        built = build_all(force="--force" in sys.argv[1:])
    except BuildError as exc:
        sys.exit(str(exc))
    for ident, path in built.items():
        print(f"{ident}: {path.relative_to(ROOT)}")
