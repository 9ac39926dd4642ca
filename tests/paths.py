"""Where the tests find the repository's files, the third-party corpus and the command line."""
import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CONFIGS = ROOT / "configs"
THIRD_PARTY = Path(os.environ.get("WAVECOSIM_THIRD_PARTY") or ROOT.parent / "shared" / "third_party")
CLI = [sys.executable, "-m", "wavecosim"]         # the command line of the interpreter running the tests
