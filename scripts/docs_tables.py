"""Write the generated tables of the documentation from the code that defines them:

    .venv/bin/python scripts/docs_tables.py           # rewrite them (make docs does it first)
    .venv/bin/python scripts/docs_tables.py --check   # exit 1, naming the page, when one is out of date

docs/scenario.md: every key of the scenario file, from the dataclasses and tables of
wavecosim/scenario/config.py (`key_reference`). docs/outputs.md: every column of trajectory.csv and
steps.csv and every key of summary.json and metadata.json, from wavecosim/run/glossary.py, the
runner's STEP_DESCRIBED and each observer's `described`. A page holds each table between the lines
`<!-- generated: NAME -->` and `<!-- end of generated -->`; the text around them is written by hand.
"""
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "master"))

from wavecosim.run import glossary  # noqa: E402
from wavecosim.run.runner import OBSERVERS, STEP_DESCRIBED  # noqa: E402
from wavecosim.scenario.config import key_reference  # noqa: E402

DOCS = ROOT / "docs"
BLOCK = re.compile(r"(<!-- generated: (?P<name>[\w-]+) -->\n).*?(<!-- end of generated -->)", re.S)


def cell(text):
    """Text as one Markdown table cell."""
    return str(text).replace("|", "\\|").replace("\n", " ") or "–"


def table(header, rows):
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    return "\n".join(lines + ["| " + " | ".join(cell(c) for c in row) + " |" for row in rows]) + "\n"


def scenario_keys():
    out = []
    for section, rows in key_reference():
        where = f"`{section}`" if section and not section.startswith("an entry") else section or "the top level"
        out.append(f"\n### {where[0].upper() + where[1:]}\n\n")
        out.append(table(("key", "type", "default", "unit", "meaning"),
                         [(f"`{k}`", kind, default, unit, doc) for k, kind, default, unit, doc in rows]))
    return "".join(out)


def described(entries):
    return table(("column", "unit", "meaning"), [(f"`{c}`", unit, meaning) for c, (meaning, unit) in entries.items()])


def steps_columns():
    out = ["\nEvery run:\n\n", described(STEP_DESCRIBED)]
    seen = set()
    for cls in OBSERVERS:
        if cls.described and id(cls.described) not in seen:
            seen.add(id(cls.described))
            out += [f"\n{cls.when[0].upper() + cls.when[1:]}:\n\n", described(cls.described)]
    return "".join(out)


def keys(entries):
    return table(("key", "unit", "meaning"), [(f"`{k}`", unit, meaning) for k, (meaning, unit) in entries.items()])


TABLES = {
    "scenario.md": {"scenario-keys": scenario_keys},
    "outputs.md": {"trajectory-columns": lambda: described(glossary.TRAJECTORY), "steps-columns": steps_columns,
                   "summary-keys": lambda: keys(glossary.SUMMARY), "metadata-keys": lambda: keys(glossary.METADATA)},
}


def rendered(page, text):
    """The page's text with every generated block made anew; a block the page lacks is an error."""
    made = TABLES[page]
    missing = set(made) - set(m.group("name") for m in BLOCK.finditer(text))
    if missing:
        raise SystemExit(f"docs/{page}: no <!-- generated: {sorted(missing)[0]} --> block")
    return BLOCK.sub(lambda m: m.group(1) + made[m.group("name")]().lstrip("\n") + m.group(3), text)


def main(argv):
    check = "--check" in argv
    stale = []
    for page in TABLES:
        path = DOCS / page
        old = path.read_text(encoding="utf-8")
        new = rendered(page, old)
        if new != old:
            stale.append(page)
            if not check:
                path.write_text(new, encoding="utf-8")
                print(f"wrote docs/{page}")
    if check and stale:
        print(f"out of date: {', '.join('docs/' + p for p in stale)}; run scripts/docs_tables.py", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
