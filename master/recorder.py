"""Streams results to disk as a run goes, so a failure or Ctrl-C loses nothing already computed."""
import csv
import json
import math
from pathlib import Path

FLUSH_EVERY = 100


def number(x):
    """Full-precision float for CSV/JSON (shortest repr that round-trips); NaN/inf as text."""
    if isinstance(x, float) and not math.isfinite(x):
        return str(x)
    return repr(float(x)) if isinstance(x, float) else x


class CsvStream:
    """One CSV file written row by row and flushed regularly."""

    def __init__(self, path: Path, columns):
        path.parent.mkdir(parents=True, exist_ok=True)
        self.path = path
        self._file = open(path, "w", newline="")
        self._writer = csv.writer(self._file)
        self._writer.writerow(columns)
        self._rows = 0

    def write(self, row):
        self._writer.writerow([number(x) for x in row])
        self._rows += 1
        if self._rows % FLUSH_EVERY == 0:
            self._file.flush()

    def close(self):
        if not self._file.closed:
            self._file.close()


def clean_json(obj):
    """JSON-safe copy: non-finite floats become strings, numpy scalars plain numbers."""
    if isinstance(obj, dict):
        return {str(k): clean_json(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [clean_json(v) for v in obj]
    if hasattr(obj, "item") and not isinstance(obj, (list, dict)):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return str(obj)
    return obj


def write_json(path: Path, data):
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".json.part")
    tmp.write_text(json.dumps(clean_json(data), indent=2) + "\n")
    tmp.replace(path)
