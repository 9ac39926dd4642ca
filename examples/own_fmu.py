"""Run a scene whose subsystem is an FMU given by its path (here one built by this repository, as
a user would point at an FMU exported from their own tool), and read the result as arrays.

    python examples/own_fmu.py
"""
import tempfile
from pathlib import Path

import wavecosim as wc
from wavecosim.fmi.builtin import builtin_fmus

SCENE = """
name: my_oscillators
dt: 0.01
T: 1.0
gamma: 0.4
subsystems:
  A: {{fmu: DuffingSide, start: {{q1: 0.4, d: -0.4}}}}
  B: {{fmu: {fmu}, parameters: {{m2: 4.0, k2: 50.0}}, port: {{physical_in: F, input: effort}}}}
couplings:
  - {{type: equal_effort_opposite_flow, ports: [A, B]}}
master: {{algorithm: dr, K: 20}}
outputs: {{q1: A.q1, q2: B.q2}}
error: [q1, q2]
"""


def main():
    fmu = builtin_fmus()["LinearSide"]                       # any .fmu file on disk
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "scene.yaml"
        path.write_text(SCENE.format(fmu=fmu))
        result = wc.simulate(path)
    traj = result.trajectory
    print(f"{len(traj)} rows, fields {traj.dtype.names}; max error {result.summary['max_error']:.2e}")
    return result


if __name__ == "__main__":
    main()
