"""Bounded resources: an FMU's messages (the last few in memory, a capped log file), archives that
unpack to too much (FMU and .ssp: refused in one line), the SSP cache, the temporary folders."""
import os
import subprocess
import tempfile
import zipfile

import pytest
import yaml

from paths import CLI
from wavecosim.errors import ConfigError, FmuError
from wavecosim.fmi import messages, unpack
from wavecosim.fmi.fmu import extract_fmu
from wavecosim.fmi.messages import LogFile, MessageLog
from wavecosim.scenario.ssp import archive


def test_an_fmus_messages_are_kept_in_a_ring_and_a_capped_file(tmp_path, monkeypatch):
    monkeypatch.setattr(messages, "FILE_MESSAGES", 5)
    log = MessageLog("B")
    for k in range(3):
        log.append((1, f"early {k}"))
    file = LogFile(tmp_path / "fmu_log.txt")
    log.attach(file)
    for k in range(100):
        log.append((1, f"step {k} " + "x" * 3000))
    assert len(log.recent) == messages.KEEP and log.count == 103
    assert log.last().startswith("step 99 xxx") and log.last().endswith("... (3008 characters)")
    file.close()
    lines = (tmp_path / "fmu_log.txt").read_text().splitlines()
    assert lines[:3] == ["B: Warning: early 0", "B: Warning: early 1", "B: Warning: early 2"]
    assert len(lines) == 6 and lines[-1].startswith("... 98 further messages not written")


def test_a_chatty_fmu_run_writes_its_log_beside_the_rows(tmp_path, faulty_scenario):
    raw = faulty_scenario(T=0.05, log_bytes=200)
    (tmp_path / "chatty.yaml").write_text(yaml.safe_dump(raw))
    proc = subprocess.run([*CLI, "run", str(tmp_path / "chatty.yaml"), "--out", str(tmp_path / "out"), "--quiet",
                           "--no-reference", "--no-certificates", "--K", "2"], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    lines = (tmp_path / "out" / "fmu_log.txt").read_text().splitlines()
    assert len(lines) == 5 * 3                         # K + 1 doSteps a macro-step, each logs once
    assert lines[0].startswith("B: Warning: fmi2DoStep: at t = 0: step 0 of FaultySide: ....")


def bomb(path, size, member="modelDescription.xml"):
    """A zip whose one member is `size` zero bytes (it compresses about 1000 to 1)."""
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        with z.open(member, "w", force_zip64=True) as f:
            chunk = bytes(1 << 20)
            for _ in range(size >> 20):
                f.write(chunk)
    return path


def test_an_fmu_that_unpacks_to_too_much_is_refused_in_one_line(tmp_path):
    fmu = bomb(tmp_path / "Bomb.fmu", 120 << 20)
    assert fmu.stat().st_size < 1 << 20
    before = set(os.listdir(tempfile.gettempdir()))
    with pytest.raises(FmuError) as info:
        extract_fmu(fmu)
    assert str(info.value) == (f"{fmu}: unpacks to 126 MB, over the limit of 105 MB (100 times the archive, at most "
                               f"2 GB): not unpacked")
    assert set(os.listdir(tempfile.gettempdir())) - before == set()


def test_an_ssp_that_unpacks_to_too_much_is_refused_and_the_cache_is_bounded(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    ssp = bomb(tmp_path / "Bomb.ssp", 120 << 20, "SystemStructure.ssd")
    with pytest.raises(ConfigError, match="unpacks to 126 MB, over the limit"):
        archive.extract_ssp(ssp)
    assert not archive.cache_root().exists() or list(archive.cache_root().iterdir()) == []
    monkeypatch.setattr(archive, "CACHE_KEEP", 2)
    made = []
    for k in range(4):
        small = tmp_path / f"s{k}.ssp"
        with zipfile.ZipFile(small, "w") as z:
            z.writestr("SystemStructure.ssd", f"<ssd {k}/>")
        made.append(archive.extract_ssp(small))
        os.utime(made[-1], (k, k))                 # in order of use
    assert sorted(p.name for p in archive.cache_root().iterdir()) == sorted(p.name for p in made[-2:])


def test_the_unpack_limit():
    assert unpack.limit(1000) == 100 << 20 and unpack.limit(100 << 20) == 2 << 30
