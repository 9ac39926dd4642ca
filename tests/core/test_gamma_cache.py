"""The gamma choice of `gamma: auto` is a pure function of the scene's coupling and the probes, so it
is searched once: a run's lockstep reference, and a later process (the build cache's gamma folder),
take the same choice without searching again; other probes search anew. (The search itself is
replaced by a stand-in here: what is under test is that it runs once per set of inputs.)"""
import dataclasses

from paths import CONFIGS
from wavecosim.core import gamma
from wavecosim.core.gamma import GammaChoice, GammaTuner
from wavecosim.core.scene import build_scene
from wavecosim.scenario.config import load_scenario


def choice(sc):
    scene = build_scene(sc)
    try:
        return GammaTuner(scene, "auto").initial([0.0] * scene.n_channels)
    finally:
        scene.close()


def test_the_search_runs_once_per_inputs_across_runs_and_processes(tmp_path, monkeypatch, built_fmus):
    monkeypatch.setattr(gamma, "cache_dir", lambda: tmp_path)      # the build cache, its gamma folder here
    searched = []

    def search(scene, probes, mode, where, secant, ceiling):
        searched.append(probes[0].dE.tolist())
        return GammaChoice({p.name: 0.5 + 0.25 * len(searched) for p in probes}, mode,
                           {p.name: float("inf") for p in probes}, 0.1 / 3.0, True)
    monkeypatch.setattr(gamma, "_choose_gamma", search)
    monkeypatch.setattr(gamma, "_CHOICES", {})
    sc = load_scenario(CONFIGS / "foreign_pair.yaml")
    first = choice(sc)
    assert len(searched) == 2 and first.gammas == {"A": 1.0, "B": 1.0}     # probed twice: at 0.4, then at 0.75
    assert dataclasses.asdict(choice(sc)) == dataclasses.asdict(first) and len(searched) == 2   # the reference
    monkeypatch.setattr(gamma, "_CHOICES", {})                 # a fresh process: nothing in memory
    assert dataclasses.asdict(choice(sc)) == dataclasses.asdict(first) and len(searched) == 2
    assert len(list((tmp_path / "gamma").glob("*.json"))) == 2
    other = dataclasses.replace(sc, subsystems=[dataclasses.replace(sc.subsystems[0], parameters={"m": 2.0, "c": 0.0}),
                                                sc.subsystems[1]])
    choice(other)
    assert len(searched) == 4
