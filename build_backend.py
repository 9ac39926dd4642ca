"""The build backend: setuptools', with what the wheel's compile step (setup.py) imports added to a
wheel's build requirements only, so an editable install (`make run`, `make test`), which compiles
nothing at install time, does not fetch them."""
from setuptools import build_meta
from setuptools.build_meta import *  # noqa: F401,F403 (the PEP 517 hooks, one replaced below)

# fmpy: the official FMI headers (the ones a run's FMUs are loaded against); numpy, sympy and pyyaml:
# the FMUs generated from specs/
COMPILE_REQUIRES = ["fmpy", "numpy", "sympy", "pyyaml"]


def get_requires_for_build_wheel(config_settings=None):
    """setuptools' requirements for a wheel and the compile step's."""
    return build_meta.get_requires_for_build_wheel(config_settings) + COMPILE_REQUIRES
