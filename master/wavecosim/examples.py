"""The example scenarios shipped inside the package (`wavecosim examples` lists them):

    import wavecosim.examples as ex
    wc.simulate(ex.path("two_oscillators"), K=5)

DEFAULT is the scene `wavecosim run` runs without a CONFIG: the paper's benchmark (Table I).
"""
import os
from pathlib import Path

CONFIGS = (Path(__file__).resolve().parent / "data" / "configs").resolve()
DEFAULT = CONFIGS / "two_oscillators.yaml"


def names():
    """The example scenarios' names (scenario files and SSP systems), sorted."""
    return sorted(p.stem if p.suffix == ".yaml" else p.name for p in CONFIGS.iterdir()
                  if p.suffix in (".yaml", ".ssd"))


def path(name) -> Path:
    """The file of an example scenario: `two_oscillators`, `two_oscillators.yaml` or `two_oscillators.ssd`."""
    found = CONFIGS / name if Path(name).suffix else CONFIGS / f"{name}.yaml"
    if not found.is_file():
        raise FileNotFoundError(f"no example scenario {name!r}; the examples are: {', '.join(names())}")
    return found


def third_party():
    """The folder of third-party FMUs and systems some examples use ($WAVECOSIM_THIRD_PARTY, else
    ../shared/third_party beside a source checkout), or None when it is absent."""
    folder = Path(os.environ.get("WAVECOSIM_THIRD_PARTY") or CONFIGS.parent.parent / "shared" / "third_party")
    return folder if folder.is_dir() else None
