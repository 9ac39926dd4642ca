"""Cost linear in the number of subsystems, with the numbers of the dense coupling to the last bit.

Claims: P and J_L are block diagonal over the connected components of the coupling, and compiling
them per component gives the values of the whole-matrix compile on every shipped scene; the sparse
products (Python and C kernel) equal the dense sums bit for bit, so on every shipped scene, K = 0
and 50, the fast path with sparse maps gives the steps of the Python reference with the dense maps
of the whole-matrix compile; `repeat:` writes N identical entries in one and gives the same
Scenario as the N copies; the instances of one FMU in one scene share one extraction.
"""
import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from paths import ROOT
from wavecosim.core import interconnection as ic
from wavecosim.kernel import linalg
from wavecosim.bench.scale import chain_raw, chain_scenario
from wavecosim.scenario.config import load_raw, load_scenario, parse_scenario
from wavecosim.errors import ConfigError, FmuError
from wavecosim.kernel.drkernel import Kernel
from wavecosim.kernel.linalg import Sparse, matvec
from wavecosim.masters.dr import DRMaster
from wavecosim.masters.dr_fast import FastDRMaster
from wavecosim.core.scene import build_scene

CONFIGS = [p for p in sorted((ROOT / "configs").glob("*.yaml"))    # scenes, not SSP port overlays
           if p.stem != "chain_512" and "ports" not in yaml.safe_load(p.read_text(encoding="utf-8"))]   # (chain_64 below)
THIRD_PARTY = ROOT.parent / "shared" / "third_party"
STEPS = 20


def dense_compile(E, F, gammas):
    """The whole-matrix compile: P = left^-1 right, J_L = (2I - P)^-1, by the same LU on every column."""
    g = np.asarray(gammas, float)
    left, right = F / np.sqrt(g) + E * np.sqrt(g), F / np.sqrt(g) - E * np.sqrt(g)
    P = ic._snap(linalg.solve_columns(left, right))
    return P, linalg.solve_columns(2.0 * np.eye(len(g)) - P, np.eye(len(g)))


def bits(x):
    return np.asarray(x, dtype=float).tobytes()


def needs_third_party(path):
    return "third_party" in path.read_text(encoding="utf-8") and not THIRD_PARTY.exists()


def test_sparse_matvec_has_the_bits_of_the_dense_sum():
    rng = np.random.default_rng(3)
    for n in (1, 5, 40):
        M = rng.normal(size=(n, n)) * (rng.random((n, n)) < 0.2)
        M[0, :] = 0.0                                          # an empty row gives +0.0, as the dense sum
        x = rng.normal(size=n)
        x[::3] = -0.0
        S = Sparse.from_dense(M)
        assert bits(matvec(S, list(x))) == bits(matvec(M.tolist(), list(x)))
        assert bits(np.asarray(S)) == bits(M + 0.0)             # -0.0 entries come back as +0.0
        assert S.nnz == np.count_nonzero(M)


def test_chain_couples_in_blocks_and_the_maps_stay_linear_in_size(built_fmus):
    scene = build_scene(chain_scenario(64))
    try:
        comps = ic.components(scene.E, scene.F)
        assert len(comps) == 63 + 2 and max(len(c[0]) for c in comps) == 2
        w = scene.wave_map()
        assert w.P_sparse.nnz == 128 and w.J_L_sparse.nnz == 2 * 63 * 2 + 2
        P, J_L = dense_compile(scene.E, scene.F, scene.channel_gammas())
        assert np.array_equal(w.P, P) and np.array_equal(w.J_L, J_L)
    finally:
        scene.close()


@pytest.mark.parametrize("path", CONFIGS, ids=lambda p: p.stem)
def test_per_component_compile_equals_the_whole_matrix_compile(path, built_fmus):
    if needs_third_party(path):
        pytest.skip("third-party FMUs not present")
    scene = build_scene(load_scenario(path))
    try:
        rng = np.random.default_rng(7)
        for trial in range(3):
            g = scene.channel_gammas() if trial == 0 else list(rng.uniform(0.01, 100.0, scene.n_channels))
            w = ic.compile_wave_map(scene.E, scene.F, g)
            P, J_L = dense_compile(scene.E, scene.F, g)
            assert np.array_equal(w.P, P) and np.array_equal(w.J_L, J_L)       # values, so bits up to the sign of 0
    finally:
        scene.close()


def dense_reference(scene, settings):
    """The Python reference DRMaster with the dense maps of the whole-matrix compile."""
    master = DRMaster(scene, settings)
    P, J_L = dense_compile(scene.E, scene.F, scene.channel_gammas())
    master.P, master.J_L = P.tolist(), J_L.tolist()
    return master


def heavy_slow(path, K):
    """The case as a parameter, marked slow where it costs the most: K = 50 on heavy_chain_8 and on
    the third-party scenes (their K = 0 cases compile the same sparse maps)."""
    heavy = K > 0 and getattr(path, "stem", path) in ("heavy_chain_8", "dcmotor", "dcmotor_shaft", "fmi3_damper")
    return pytest.param(path, K, marks=pytest.mark.slow) if heavy else pytest.param(path, K)


@pytest.mark.parametrize("path, K", [heavy_slow(p, K) for p in CONFIGS + ["chain_64"] for K in (0, 50)],
                         ids=lambda x: getattr(x, "stem", str(x)))
def test_sparse_fast_path_gives_the_steps_of_the_dense_reference(path, K, built_fmus):
    if path != "chain_64" and needs_third_party(path):
        pytest.skip("third-party FMUs not present")
    scenario = chain_scenario(64) if path == "chain_64" else load_scenario(path)
    steps = 8 if path == "chain_64" else STEPS
    settings = dataclasses.replace(scenario.master, K=K, eps=None, deadline_us=None, fast="auto", threads="1")
    scenes = [build_scene(scenario), build_scene(scenario)]
    masters = [dense_reference(scenes[0], settings), FastDRMaster(scenes[1], settings)]
    try:
        for n in range(steps):
            logs = [m.step(n, n * scenario.dt) for m in masters]
            assert bits(logs[0].a_hat) == bits(logs[1].a_hat), f"a differs at step {n}"
            assert bits(masters[0].b) == bits(masters[1].b), f"b differs at step {n}"
            assert logs[0].iterations == logs[1].iterations
            assert math.isnan(logs[0].residual) == math.isnan(logs[1].residual)
    finally:
        for m in masters:
            m.close()
        for s in scenes:
            s.close()


def test_kernel_refuses_malformed_sparse_rows(built_fmus):
    scene = build_scene(chain_scenario(8))
    try:
        w = scene.wave_map()
        kernel = Kernel(scene.kernel_scene(), w.P_sparse, w.J_L_sparse)
        try:
            bad = Sparse(w.P_sparse.n, w.P_sparse.start, w.P_sparse.col + 100, w.P_sparse.val)
            with pytest.raises(FmuError, match="refused the coupling maps"):
                kernel.set_maps(bad, w.J_L_sparse)
        finally:
            kernel.close()
    finally:
        scene.close()


def without_labels(sc):
    return dataclasses.replace(sc, name="", description="", source="")


def test_repeat_gives_the_scenario_of_the_written_out_copies(built_fmus):
    written = load_scenario(ROOT / "configs" / "chain.yaml")
    repeated = parse_scenario(chain_raw(8), "<repeat>", ROOT / "configs")
    assert without_labels(repeated) == without_labels(written)
    big = load_scenario(ROOT / "configs" / "chain_512.yaml")
    assert [s.name for s in big.subsystems] == [f"L{i}" for i in range(512)]
    assert big.couplings[1].ports == ["L0[1]", "L1[0]"] and big.couplings[511].ports == ["L510[1]", "L511[0]"]
    assert big.outputs == {f"q{i}": f"L{i}.q" for i in range(8)} and big.error == list(big.outputs)


def test_repeat_expressions_and_set_keys(tmp_path):
    raw = chain_raw(4)
    raw["couplings"][1]["ports"] = ["L{i}[1]", "L{1*i+1}[0]"]
    raw["subsystems"]["L{i}"]["start"] = {"q": "{2*i-2}", "v": 0.0, "d": 0.0}
    sc = parse_scenario(raw, "<x>")
    assert [c.ports for c in sc.couplings[1:4]] == [["L0[1]", "L1[0]"], ["L1[1]", "L2[0]"], ["L2[1]", "L3[0]"]]
    assert [s.start["q"] for s in sc.subsystems[1:]] == [0, 2, 4]
    path = tmp_path / "c.yaml"
    path.write_text((ROOT / "configs" / "chain_512.yaml").read_text(encoding="utf-8"), encoding="utf-8")
    assert load_raw(path)["subsystems"]["L300"]["parameters"]["k"] == 100.0     # --set sees every copy


@pytest.mark.parametrize("change, key, needle", [
    (lambda r: r["subsystems"]["L{i}"].update(repeat={"i": "5..2"}), "subsystems.L{i}.repeat", "a <= b"),
    (lambda r: r["subsystems"]["L{i}"].update(repeat={"i": "1..3", "j": "1..2"}), "subsystems.L{i}.repeat",
     "one index"),
    (lambda r: r["subsystems"]["L{i}"].update(repeat={"i": "0..3"}), "subsystems.L{i}", "'L0', which is already"),
    (lambda r: r["couplings"][1].update(repeat="0..3"), "couplings[1].repeat", "one index"),
])
def test_a_bad_repeat_is_one_line_naming_its_key(change, key, needle):
    raw = chain_raw(4)
    change(raw)
    with pytest.raises(ConfigError) as exc:
        parse_scenario(raw, "f.yaml")
    text = str(exc.value)
    assert "\n" not in text and text.startswith(f"f.yaml: {key}") and needle in text


def test_instances_of_one_fmu_in_a_scene_share_one_extraction(built_fmus):
    scene = build_scene(chain_scenario(8))
    folders = {Path(s.fmu.folder) for s in scene.subsystems}
    other = build_scene(chain_scenario(2))
    try:
        assert len(folders) == 1 and all(f.exists() for f in folders)
        assert {Path(s.fmu.folder) for s in other.subsystems}.isdisjoint(folders)   # a scene of its own
    finally:
        other.close()
        scene.close()
    assert not any(f.exists() for f in folders)
