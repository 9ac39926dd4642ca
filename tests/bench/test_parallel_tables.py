"""`wavecosim bench --only parallel_threads` and the script that writes docs/parallel.md's tables from it
(scripts/parallel_tables.py): rows for 1, 2, 4 and 8 threads, and the page's tables replaced from the
files, never copied by hand. The figures themselves are measured, never asserted against the clock."""
import json
import shutil
import subprocess
import sys

import pytest

from paths import ROOT
from wavecosim.cli import main
from wavecosim.kernel.drkernel import available_cpus
from wavecosim.run.distributed import round_trips
from wavecosim.scenario.config import load_scenario


@pytest.mark.slow
def test_parallel_threads_rows_and_the_docs_tables(built_fmus, tmp_path, capsys):
    bench = tmp_path / "bench.json"
    with pytest.raises(SystemExit) as exit_:
        main(["bench", "--only", "parallel_threads", "--quick", "--json", str(bench)])
    assert exit_.value.code == 0
    p = json.loads(bench.read_text())["parallel_threads"]
    assert [r["threads"] for r in p["rows"]] == [1, 2, 4, 8]
    assert [r["threads_used"] for r in p["rows"]] == [min(n, available_cpus(), 8) for n in (1, 2, 4, 8)]
    assert p["subsystems"] == 8 and p["floor_us_per_step"] == (p["K"] + 1) * max(p["us_per_eval"])
    assert all(r["ideal_us_per_step"] >= p["floor_us_per_step"] for r in p["rows"])
    assert "ideal µs/step" in capsys.readouterr().out
    scenario = load_scenario(ROOT / "configs" / "chain.yaml").with_master(energy_guard="off")
    rt = tmp_path / "rt.json"
    rt.write_text(json.dumps({"cpus": 2, "rounds": 200, "load_average_1min": [0.0, 0.0], "us_per_round_trip":
                              {"shm": {str(w): v for w, v in round_trips(scenario, "shm", (1, 2)).items()}}}))
    page = tmp_path / "parallel.md"
    shutil.copy(ROOT / "docs" / "parallel.md", page)
    subprocess.run([sys.executable, str(ROOT / "scripts" / "parallel_tables.py"), "write", str(bench), str(rt),
                    str(page)], check=True, capture_output=True)
    text = page.read_text()
    for row in p["rows"]:
        assert f"| {row['threads']} | {row['threads_used']} | {row['us_per_step']:.0f} |" in text
    assert "| engine | 1 worker | 2 workers |" in text and "| shm | " in text
