"""What the parent of a supervised run writes when the child died without finishing (run/supervisor.py):
each run's CSV files cut after their last whole line and completed with the rows the child committed
that they lack (from its tables' shared memory, run/durable.py), and a summary.json from the status
channel (the rows on disk, the status, the fault's subsystem, call and step)."""
import json
import os
import signal
from pathlib import Path

from ..kernel.guard import signal_name
from .channel import describe, locate
from .durable import ROWS, WHOLE, Mapped, texts_met
from .recorder import BLOCK, PAD, formatter, header, write_json


def salvage(channel, wait_status, summary_path, step_timeout, cause=None):
    """The error that ended the child; the runs' files made whole and their summary.json written.
    cause: (error class, message) when the parent ended the child itself (it did not answer)."""
    status, layout = channel.status, channel.layout()
    complete_rows(channel.folder)
    fault = status.fault.summary() or _death(wait_status)
    parts = (layout or {}).get("parts", [])
    subsystems = {folder: name + (" (monolithic reference)" if part["reference"] else "")
                  for part in parts for name, folder in part["subsystems"].items()}
    where = locate(fault.get("pc", []), (layout or {}).get("libraries", []), subsystems)
    kept = {part["label"]: whole_rows(part["files"].get("trajectory")) for part in parts}
    error = describe(fault, status.request, where, None, None, step_timeout)
    if cause is not None:
        cls, message = cause
        who, call = where
        error = cls(f"{message}; inside {who} in {call}" if who and call else message)
    for part in parts:
        whole_rows(part["files"].get("steps"))
        steps = max(kept[part["label"]] - 2, 0)        # the header and the row at t = 0
        message = f"{error}; {steps} steps kept"
        summary = Path(part["out_dir"]) / f"summary{part['suffix']}.json" if part["out_dir"] else None
        if summary is not None:
            write_json(summary, {"label": part["label"], "scenario": part["scenario"], "master": part["master"],
                                 "K": part["K"], "dt": part["dt"], "T": part["T"], "steps": steps,
                                 "status": error.status, "message": message, "fault": fault})
    if not parts and summary_path is not None and summary_path.parent.is_dir():
        write_json(summary_path, {"steps": 0, "status": error.status, "message": f"{error} (during set-up)",
                                  "fault": fault})
    main = next((p for p in parts if not p["reference"]), None)
    tail = f"; {max(kept[main['label']] - 2, 0)} steps kept" if main is not None else " (during set-up)"
    return type(error)(f"{error}{tail}")


def complete_rows(folder):
    """Every durable run's CSV files in a channel folder completed with the committed rows they lack
    (from its tables' shared memory; rows.json: LiveRun._describe_rows), whatever ended the child."""
    for described in Path(folder).glob("rows-*/rows.json"):
        try:
            _complete(json.loads(described.read_text()), texts_met(described.with_name("texts.jsonl")))
        except (OSError, ValueError):         # the files as they are: the summary counts what they hold
            pass


def _complete(described, texts):
    """One run's two tables, each up to as many steps as both hold (a step's trajectory row follows
    the t = 0 row); the late columns of the rows of a block in progress are left empty. texts: the
    trajectory's String columns' texts met (TextLog)."""
    for j, met in texts.items():
        described["trajectory"]["formats"][j] = {"texts": met}
    tables = {kind: (table, Mapped(table["memory"], BLOCK, BLOCK + PAD, len(table["columns"]), create=False))
              for kind, table in described.items()}
    steps = min(tables["steps"][1].record[ROWS], tables["trajectory"][1].record[ROWS] - 1)
    for kind, (table, memory) in tables.items():
        try:
            _append_rows(table, memory, steps + (kind == "trajectory"))
        except OSError:                       # the disk full: the rows it took stay, and the other table goes on
            pass


def _append_rows(table, memory, upto):
    """The rows the file lacks up to row `upto` - 1 (after the whole pieces its writer wrote), written
    from the table's blocks as the writer writes them; whole rows only (a write that fails, the disk
    full, leaves those it wrote whole)."""
    have, size = memory.filed()
    if upto <= have:
        return
    path = table["csv"]
    with open(path, "a+b", buffering=0) as f:
        if f.seek(0, os.SEEK_END) < size:            # shorter than its writer left it: its whole rows
            have, size = max(whole_rows(path) - 1, 0), os.path.getsize(path)
        f.truncate(size)
        text = memoryview("".join(line + "\r\n" for line in _lines(table, memory, have, upto, size == 0)).encode())
        try:
            while text:
                text = text[f.write(text):]
        except OSError:
            whole_rows(path)
            raise


def _lines(table, memory, have, upto, head):
    """Rows have .. upto - 1 of a table from its blocks as CSV lines (after the header when `head`)."""
    formats, late = [formatter(f) for f in table["formats"]], set(table["late"])
    lines = [header(table["columns"])] if head else []
    for slot, at, count in memory.rows_at(have, upto):
        block = memory.block(slot, create=False)[at:at + count]
        whole = max(0, min(count, memory.record[WHOLE] - have))     # rows of these whose late columns are written
        cells = [fmt(block[:whole if j in late else count, j]) for j, fmt in enumerate(formats)]
        for j in late:
            cells[j] += [""] * (count - whole)
        lines += [",".join(row) for row in zip(*cells)]
        have += count
    return lines


def _death(wait_status):
    """A fault record for a child that died with no record of its own (killed outright)."""
    if wait_status is not None and os.WIFSIGNALED(wait_status):
        number = os.WTERMSIG(wait_status)
        return {"kind": "signal", "signal": signal_name(number), "code": 0, "pc": [],
                "killed": number == signal.SIGKILL}
    code = os.WEXITSTATUS(wait_status) if wait_status is not None else None
    return {"kind": "exit", "code": code, "pc": []}


def whole_rows(path):
    """Cut a CSV file after its last whole line (a death may leave half a row); its line count."""
    if not path or not os.path.exists(path):
        return 0
    with open(path, "rb+") as f:
        size = f.seek(0, os.SEEK_END)
        end, chunk = size, 1 << 16
        while end > 0:
            start = max(0, end - chunk)
            f.seek(start)
            block = f.read(end - start)
            at = block.rfind(b"\n")
            if at >= 0:
                end = start + at + 1
                break
            end = start
        if end != size:
            f.truncate(end)
        f.seek(0)
        return sum(block.count(b"\n") for block in iter(lambda: f.read(1 << 20), b""))
