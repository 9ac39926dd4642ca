"""master/frozen_port_map.py: a query never moves the committed state, the commit does, the calls
are counted, and the raw reader agrees with fmpy's getReal."""
import pytest

from wavecosim.config import load_scenario
from wavecosim.scene import build_scene


@pytest.fixture()
def scene():
    s = build_scene(load_scenario())
    yield s
    s.close()


def test_query_discards_and_advance_keeps(scene):
    A = scene.subsystems[0]
    names = ["q1", "v1", "d"]
    A.freeze(0, 0.0)
    before = list(A.read(names))
    first = A.query([0.7])
    assert A.query([0.7]) == first                      # the same x^n each time
    A.thaw()
    assert list(A.read(names)) == before
    assert A.advance([0.7]) == first and list(A.read(names)) != before
    assert A.calls == {"doStep": 3, "save": 1, "restore": 2}


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


def test_kernel_steps_are_booked_like_python_steps(scene):
    A = scene.subsystems[0]
    A.note_kernel_step(4, 0.04, iterations=7)
    assert (A.step_index, A.t) == (4, 0.04) and A.calls == {"doStep": 8, "save": 1, "restore": 7}
