"""Scenes several test modules build on (plain mappings of a scenario file)."""

# A Duffing side and an oscillator coupled at a power port, and a LinearSide S joined to them by
# signals only: the signal tests add their sources, signals and outputs.
SIGNAL_SCENE = {
    "name": "signals", "dt": 0.01, "T": 0.2, "gamma": 0.4,
    "subsystems": {
        "A": {"fmu": "DuffingSide", "start": {"q1": 0.4, "d": -0.4},
              "port": {"wave_in": "a", "wave_out": "b", "effort": "e", "flow": "f", "physical_in": "u",
                       "input": "flow"}},
        "B": {"fmu": "Oscillator", "parameters": {"m": 4.0, "k": 50.0},
              "port": {"wave_in": "a_left", "wave_out": "b_left", "effort": "e_left", "flow": "f_left",
                       "physical_in": "F_left", "input": "effort"}},
        "S": {"fmu": "LinearSide", "parameters": {"m2": 1.0, "k2": 10.0}},
    },
    "couplings": [{"type": "equal_effort_opposite_flow", "ports": ["A", "B"]}],
}
