import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="session")
def built_fmus():
    """{identifier: Path} of every FMU built from models/ by fmus/build.py."""
    spec = importlib.util.spec_from_file_location("wavecosim_fmu_build", ROOT / "fmus" / "build.py")
    build = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(build)
    return build.build_all(log=lambda msg: None)
