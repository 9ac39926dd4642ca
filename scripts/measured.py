"""What the scripts that measure a docs table share: their rows kept in a folder (or read back with
--again) and the table written into its page between `<!-- measured: NAME -->` and
`<!-- end of measured -->`."""
import json
import re
import sys
from pathlib import Path


def rows(path, measure, again):
    """The rows: measured now and kept in `path`, or read back from it (again)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if again:
        return json.loads(path.read_text())
    found = measure()
    path.write_text(json.dumps(found, indent=1))
    return found


def write(page, name, text):
    """The page with the block `name` holding `text` (ending in a newline)."""
    block = re.compile(rf"(<!-- measured: {name} -->\n).*?(<!-- end of measured -->)", re.S)
    page.write_text(block.sub(lambda m: m.group(1) + text + m.group(2), page.read_text()))


def arguments(default):
    """(the rows' folder, again) from the command line: [OUT] [--again]."""
    given = [a for a in sys.argv[1:] if not a.startswith("--")]
    return (Path(given[0]) if given else default), "--again" in sys.argv
