"""master/frozen_port_map.py: a query never moves the committed state, the commit does, the calls
are counted, and the raw reader agrees with fmpy's getReal."""
import numpy as np
import pytest

from wavecosim.scenario.config import load_scenario
from wavecosim.core.scene import build_scene


@pytest.fixture()
def scene():
    s = build_scene(load_scenario())
    yield s
    s.close()


def since(start, A):
    """The calls of A's FMU since its counts were `start`."""
    return {k: v - start[k] for k, v in A.calls.items()}


def test_query_discards_and_advance_keeps(scene):
    A = scene.subsystems[0]
    names = ["q1", "v1", "d"]
    start = A.calls
    A.freeze(0, 0.0)
    before = list(A.read(names))
    first = A.query([0.7])
    assert A.query([0.7]) == first                      # the same x^n each time
    A.thaw()
    assert list(A.read(names)) == before
    assert A.advance([0.7]) == first and list(A.read(names)) != before
    # three reads of the names (a get each), three queries (a set, a doStep and a get each)
    assert since(start, A) == {"doStep": 3, "save": 1, "restore": 2, "get": 6, "set": 3}


def test_restore_frozen_undoes_a_commit(scene):
    A = scene.subsystems[0]
    A.freeze(0, 0.0)
    b = A.advance([0.2])
    A.restore_frozen()
    assert A.advance([0.2]) == b


def test_reader_reads_what_fmpy_reads(scene):
    B = scene.subsystems[1]
    B.freeze(0, 0.0)
    B.advance([0.4])
    read, buf = B.reader(["q2", "v2", "H"])
    assert read() is buf and list(buf) == list(B.fmu.get_real(B.fmu.vrs(["q2", "v2", "H"])))


def test_a_kernel_step_moves_the_subsystem_and_counts_nothing_itself(scene):
    """The kernel counts its calls in the FMU's counters where it makes them; noting its step books none."""
    A = scene.subsystems[0]
    start = A.calls
    A.note_kernel_step(4, 0.04)
    assert (A.step_index, A.t) == (4, 0.04) and A.calls == start


@pytest.mark.parametrize("dirty", [False, True], ids=["just-frozen", "after-a-query"])
def test_queries_in_one_call_are_the_queries_one_by_one(scene, dirty):
    """raw_queries makes the same FMU calls as raw_query row by row: the same outputs to the bit,
    the same counts, and the instance left where those would leave it."""
    A = scene.subsystems[0]
    rows = np.random.default_rng(4).standard_normal((9, A.m))
    results = []
    for batch in (False, True):
        start = A.calls
        A.freeze(3, 0.03)
        if dirty:
            A.raw_query([0.5])
        out = A.raw_queries(rows) if batch else np.array([A.raw_query(list(r)) for r in rows])
        A.thaw()
        results.append((out.tobytes(), since(start, A), list(A.read(["q1", "v1", "d"]))))
    assert results[0] == results[1] and results[0][1]["doStep"] == 9 + dirty
