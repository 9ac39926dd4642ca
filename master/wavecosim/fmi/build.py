"""Build every model of the package's data (models/ and the port-Hamiltonian specs/) into an FMI 2.0
co-simulation FMU in the per-user cache (wavecosim.kernel.build).

One loop: for each model folder, compile the shared FMI layer (fmus/layer) with the model into
binaries/linux64/<Id>.so, print modelDescription.xml from the same tables, zip into <Id>.fmu.
A build whose sources and flags are unchanged is found in the cache and not redone.
"""
import importlib.util
import re
import shutil
import tempfile
import zipfile
from pathlib import Path

from ..kernel.build import (CFLAGS, COMPILER, BuildError, build_library, cached, fmi_headers, library_names, place,
                            prebuilt, run, stamp, target)

DATA = Path(__file__).resolve().parent.parent / "data"
LAYER = DATA / "fmus" / "layer"
CODEGEN = DATA / "fmus" / "codegen"
MODELS = DATA / "models"
SPECS = DATA / "specs"
PLATFORM = "linux64"


def layer_source(model_dir: Path) -> Path:
    """The FMI layer a model is built with: fmus/layer/fmi2_cosim.c, or the file its config.h names
    in FMI_LAYER_SOURCE (fmi2_strict.c: the strict layer of test models)."""
    m = re.search(r'#define\s+FMI_LAYER_SOURCE\s+"(\w+\.c)"', (model_dir / "config.h").read_text())
    return LAYER / (m.group(1) if m else "fmi2_cosim.c")


def model_source(model_dir: Path) -> Path:
    """The model's equations: its model.c, or the one of the model its config.h names in MODEL_SOURCE
    (a variant that differs only in what it declares, e.g. FixedStepMass of foreign_mass)."""
    m = re.search(r'#define\s+MODEL_SOURCE\s+"(\w+)"', (model_dir / "config.h").read_text())
    return (MODELS / m.group(1) if m else model_dir) / "model.c"


def _sources(model_dir: Path):
    """The layer's headers, describe.c, the model's layer, its headers and its equations."""
    layer = [p for p in LAYER.iterdir() if p.suffix == ".h" or p.name == "describe.c"]
    own = [p for p in model_dir.iterdir() if p.suffix == ".h" or (p.suffix == ".c" and p.name != "model.c")]
    return layer + [layer_source(model_dir)] + own + [model_source(model_dir)]


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
    """Compile one model into <cache>/fmus/<stamp>/<Id>.fmu (unless the package or the cache holds it);
    returns its path."""
    ident = model_identifier(model_dir)
    key = stamp(_sources(model_dir))
    if not force and (shipped := prebuilt("fmus", key, f"{ident}.fmu")):
        return shipped
    path = target("fmus", key, f"{ident}.fmu")
    return cached(path, lambda: _compile(model_dir, ident, path), force, log)


def _compile(model_dir, ident, path):
    """The FMU of one model, compiled and zipped into place at `path`."""
    includes = ["-I", fmi_headers(), "-I", LAYER, "-I", model_dir]
    with tempfile.TemporaryDirectory() as tmp:
        describe, so = Path(tmp) / "describe", Path(tmp) / f"{ident}.so"
        run([COMPILER, *CFLAGS, *includes, LAYER / "describe.c", "-o", describe], f"{ident} description")
        xml = run([describe], f"{ident} description")
        equations = Path(tmp) / "model.c"                # copied: its #include "config.h" is the model's own
        shutil.copyfile(model_source(model_dir), equations)
        run([COMPILER, *CFLAGS, "-shared", *includes, layer_source(model_dir), equations, "-o", so, "-lm",
             "-lpthread"], ident)

        members = [("modelDescription.xml", xml.encode()), (f"binaries/{PLATFORM}/{ident}.so", so.read_bytes())]
        members += [(f"sources/{src.name}", src.read_bytes()) for src in _packed_sources(model_dir)]
        return place(lambda part: _zip(part, members), path)


def _zip(path, members):
    """A zip of (name, bytes) with fixed dates, so the same sources give the same FMU bytes."""
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        for name, data in members:
            info = zipfile.ZipInfo(name, date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type, info.external_attr = zipfile.ZIP_DEFLATED, 0o644 << 16
            z.writestr(info, data)


def model_dirs():
    return sorted(p for p in MODELS.iterdir() if (p / "config.h").exists())


def generated(spec: Path) -> Path:
    """<cache>/gen/<stamp>/<spec name>/: the model folder generated from a port-Hamiltonian spec
    (fmus/codegen/ph.py), made when neither the package nor the cache holds it."""
    key = stamp([spec, *CODEGEN.glob("*.py"), *CODEGEN.glob("*.h")])
    if (shipped := prebuilt("gen", key, spec.stem)) and (shipped / "config.h").exists():
        return shipped
    out = target("gen", key, spec.stem)
    if not (out / "config.h").exists():
        out.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(dir=out.parent, prefix=f".{spec.stem}."))
        try:
            codegen().generate(spec, tmp)
            tmp.rename(out)
        except OSError:                     # another process placed it first
            if not (out / "config.h").exists():
                raise
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
    return out


def build_spec(spec: Path, force=False, log=print) -> Path:
    """The FMU of a port-Hamiltonian spec: its generated model folder, built."""
    return build_model(generated(spec), force, log)


def codegen():
    """fmus/codegen/ph.py loaded as a module (a script folder of the package data, not a package)."""
    loader = importlib.util.spec_from_file_location("wavecosim_codegen_ph", CODEGEN / "ph.py")
    ph = importlib.util.module_from_spec(loader)
    loader.loader.exec_module(ph)
    return ph


def spec_files():
    return sorted(SPECS.glob("*.yaml")) if SPECS.is_dir() else []


def build_all(force=False, log=print) -> dict:
    """Build every model, every spec and the kernel libraries (those neither the package nor the cache
    holds); returns {identifier: fmu path}."""
    fmus = {model_identifier(d): build_model(d, force, log) for d in model_dirs()}
    for spec in spec_files():
        fmus[model_identifier(generated(spec))] = build_spec(spec, force, log)
    for name in library_names():
        build_library(name, force, log)
    return fmus
