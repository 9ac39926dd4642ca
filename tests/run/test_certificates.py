"""master/certificates.py and the observers that use it, on the real Table I FMUs."""
import ctypes
import dataclasses
import json

import numpy as np
import pytest

from paths import ROOT
from wavecosim.kernel import blocks
from wavecosim.core.certificates import Sampling, augmented_residual, fne_margins, sampling
from wavecosim.scenario.config import CertificateConfig, load_scenario
from wavecosim.kernel.newton import NewtonKernel
from wavecosim.run.observers.passivity import grow_max_pos
from wavecosim.run.runner import run
from wavecosim.core.scene import build_scene
from wavecosim.core.waves import port_energy


@pytest.fixture(scope="module")
def frozen_B():
    """LinearSide of Table I frozen at t = 0: its frozen map is affine, b = rho a + c."""
    scene = build_scene(load_scenario())
    B = scene.subsystems[1]
    B.freeze(0, 0.0)
    yield B
    scene.close()


def test_fne_margin_of_an_affine_map_is_rho_minus_rho_squared(frozen_B):
    rho = frozen_B.query([1.0])[0] - frozen_B.query([0.0])[0]
    margin = fne_margins(frozen_B, [0.3], pairs=6, rng=np.random.default_rng(0), scale=0.5, dt=0.01)
    frozen_B.thaw()
    assert margin == pytest.approx(rho - rho * rho, rel=1e-6)
    assert 0 < rho < 1


def test_augmented_residual_is_storage_plus_fejer_minus_supply():
    u0, uK, u_star = [1.0, 2.0], [0.5, 1.0], [0.0, 0.0]
    a, b = [3.0, -1.0], [2.0, 0.5]
    fejer = 0.5 * (0.25 + 1.0) - 0.5 * (1.0 + 4.0)
    assert augmented_residual(0.7, u0, uK, u_star, a, b) == pytest.approx(0.7 + fejer - port_energy(a, b))


def test_port_energy_of_waves_is_the_power_integral():
    """1/2(|a|^2 - |b|^2) with discrete waves equals dt e f (eqs. 3-5)."""
    from wavecosim.core.waves import waves
    a, b = waves(2.0, -0.7, gamma=3.0, dt=0.01)
    assert port_energy([a], [b]) == pytest.approx(0.01 * 2.0 * -0.7, rel=1e-12)



def _steps(K, every):
    """Table I, 20 steps, with certificates.every = every: steps.csv as {column: array}, and the summary."""
    sc = load_scenario()
    sc = dataclasses.replace(sc.with_master(K=K), T=20 * sc.dt,
                             certificates=dataclasses.replace(sc.certificates, every=every))
    result = run(sc)
    return {c: result.steps[c] for c in result.steps.dtype.names}, result.summary


@pytest.mark.parametrize("K, fne_pairs, every", [(0, 8, 20), (3, 8, 5), (8, 8, 3), (18, 8, 2), (19, 8, 1),
                                                 (50, 8, 1), (0, 0, 4), (1, 2, 4)])
def test_auto_pacing_never_costs_more_evaluations_than_dr(K, fne_pairs, every):
    """auto: every = max(1, ceil((2 fne_pairs + 4) / (K + 1))); a master without fixed evaluations: 1."""
    config = CertificateConfig(fne_pairs=fne_pairs)
    assert sampling(config, K + 1).every == every
    assert sampling(config, None).every == 1
    assert sampling(CertificateConfig(every=7), K + 1) == Sampling(7, "certificates.every")


@pytest.mark.parametrize("K", [0, 3])
def test_every_3_samples_steps_0_3_6_and_nan_elsewhere(K):
    """The sampled columns (FNE pairs, augmented; at K < 2 the watch's probe) hold numbers at
    n % 3 == 0 only; Condition 2 and the K >= 2 watch stay every step; step 0 equals every = 1's."""
    steps, summary = _steps(K, 3)
    dense, _ = _steps(K, 1)
    sampled = np.arange(20) % 3 == 0
    assert summary["certificates_every"] == 3
    for c in ["fne_A", "fne_B", "augmented"] + (["fne_watch"] if K < 2 else []):
        assert np.isfinite(steps[c][sampled]).all() and np.isnan(steps[c][~sampled]).all(), c
        assert steps[c][0] == dense[c][0] and np.isfinite(dense[c]).all(), c
    assert summary["min_fne_margin_by_subsystem"]["A"] == steps["fne_A"][sampled].min()
    if K >= 2:
        assert np.isfinite(steps["fne_watch"][~sampled]).any()
    for c in ("r_A", "r_B", "H_total", "iterations"):           # the run itself does not change
        assert steps[c].tolist() == dense[c].tolist(), c


@pytest.mark.parametrize("config, K, every", [("two_oscillators.yaml", 0, 1), ("two_oscillators.yaml", 3, "auto"),
                                              ("two_oscillators.yaml", 50, 1), ("two_oscillators_stiff.yaml", 8, 1),
                                              ("two_oscillators_stiff.yaml", 1, "auto"), ("star.yaml", 3, "auto"),
                                              ("star.yaml", 0, 2), ("planar.yaml", 0, 3), ("planar.yaml", 4, "auto"),
                                              ("foreign_pair.yaml", 3, 1), ("unsafe", 8, 1), ("unsafe", 0, 1)])
def test_certificates_on_the_kernel_route_are_the_reference(tmp_path, monkeypatch, config, K, every):
    """With the C kernel (the certificates in the blocks by certs.c; step by step, u* by newton.c's
    nt_solve) steps.csv and every figure equal the Python reference's step by step, to the last byte
    (foreign_pair: its wave adapters' maps keep figures of their own, so u* and the rest in Python)."""
    path = ROOT / "configs" / config
    if config == "foreign_pair.yaml" and not (ROOT.parent / "shared" / "third_party").is_dir():
        pytest.skip("the third-party FMUs (../shared/third_party) are absent")
    solved = []
    solve = NewtonKernel.solve
    monkeypatch.setattr(NewtonKernel, "solve", lambda self, *a: solved.append(a[0]) or solve(self, *a))
    sc = load_scenario(ROOT / "configs" / "two_oscillators_stiff.yaml").with_changes(gamma="fast-unsafe") \
        if config == "unsafe" else load_scenario(path)                  # the watch fails: its warnings
    sc = dataclasses.replace(sc.with_master(K=K), T=min(sc.T, 100 * sc.dt),
                             certificates=dataclasses.replace(sc.certificates, every=every))
    summaries, blocked, warned = [], 0, []
    for fast in ("false", "true"):
        out = tmp_path / fast
        result = run(sc.with_master(fast=fast), out, file_suffix=False, reference=None, warn=warned.append)
        blocked = result.summary["block_steps"]
        summaries.append({k: v for k, v in result.summary.items()
                          if not k.endswith("_s") and k not in ("real_time_factor", "block_steps", "fast_path",
                                                                 "fast_note", "threads", "thread_note")})
    assert (tmp_path / "false" / "steps.csv").read_bytes() == (tmp_path / "true" / "steps.csv").read_bytes()
    assert (tmp_path / "false" / "trajectory.csv").read_bytes() == (tmp_path / "true" / "trajectory.csv").read_bytes()
    assert json.dumps(summaries[0], default=str) == json.dumps(summaries[1], default=str)
    assert warned[:len(warned) // 2] == warned[len(warned) // 2:] and (config == "unsafe") == bool(warned)
    steps, foreign, planar = summaries[1]["steps"], config == "foreign_pair.yaml", config == "planar.yaml"
    # every step in blocks, the certificates in certs.c; planar at K < 2 (two channels a port): blocks
    # between the sampled steps, made step by step with the watch's probe in Python and u* by nt_solve
    sampled = list(range(0, steps, summaries[1]["certificates_every"]))
    assert blocked == (0 if foreign else steps - len(sampled) if planar and K < 2 else steps)
    assert solved == (sampled if planar and K < 2 else [])


def _sampled_reference(certs, log, rows, k, first, every, fig):
    """CertificateSampler's block columns and figures as after_step folds them, step after step."""
    a, b, h, rounds = rows
    min_fne, max_aug, H_prev = list(fig[:k]), fig[k], fig[k + 1]
    out = np.full((len(certs), k + 1), np.nan)
    for s, row in enumerate(certs):
        H = sum(log[i, s] for i in h)
        out[s, :k] = row[:k]
        if s >= first and (s - first) % every == 0:
            min_fne = [min(m, x) for m, x in zip(min_fne, row[:k].tolist())]
            supplied = 0.5 * (sum(log[j, s] ** 2 for j in a) - sum(log[j, s] ** 2 for j in b))
            r = ((H - H_prev) + row[k]) - supplied
            out[s, k] = np.nan if log[rounds, s] > 0 else r
            max_aug = grow_max_pos(max_aug, out[s, k])
        H_prev = H
    return out, [*min_fne, max_aug, H_prev]


@pytest.mark.parametrize("first, every", [(0, 1), (2, 3), (7, 20)])
def test_sampled_block_is_the_step_by_step_fold_to_the_bit(first, every):
    """blocks.c sampled_block on values over 16 decades with NaN and signed zeros among the margins
    (builtin min keeps the first of -0.0 and 0.0, and never takes a NaN)."""
    rng, k, count = np.random.default_rng(first + every), 2, 60
    certs = rng.standard_normal((count, 3 * k + 1)) * 10.0 ** rng.integers(-8, 8, (count, 3 * k + 1))
    certs[rng.random((count, 3 * k + 1)) < 0.1] = np.nan
    certs[:, :k] = np.abs(certs[:, :k])              # the zeros below are the smallest margins
    one, two = range(first, count, every)[1:3]
    certs[one, :k], certs[two, :k] = [-0.0, 0.0], [0.0, -0.0]
    log = rng.standard_normal((12, count)) * 10.0 ** rng.integers(-8, 8, (12, count))
    log[11] = (rng.random(count) < 0.2).astype(float)                 # the ledger's redo rounds
    rows = ([0, 1], [2, 3], [4, 5], 11)
    fig = [np.inf, 1.0, np.nan, 0.5]
    want, figures = _sampled_reference(certs, log, rows, k, first, every, fig)
    c_fig = (ctypes.c_double * (k + 2))(*fig)
    place = (lambda i: ctypes.cast(ctypes.addressof(c_fig) + 8 * i, ctypes.POINTER(ctypes.c_double)))
    out = np.empty((count, k + 1), order="F")
    call = blocks.SampledBlock(count=count, k=k, n=2, nb=2, first=first, every=every, fne=1, augmented=1,
                               rounds=rows[3], log=log.ctypes.data, ld=count, certs=certs.ctypes.data,
                               ldc=3 * k + 1, out=out.ctypes.data, ldo=count, a=blocks.ints(rows[0]),
                               b=blocks.ints(rows[1]), h=blocks.ints(rows[2]), min_fne=place(0), max_aug=place(k),
                               H_prev=place(k + 1))
    blocks.library().sampled_block(ctypes.byref(call))
    assert out.tobytes() == want.tobytes()
    assert np.array(c_fig[:]).tobytes() == np.array(figures).tobytes()


@pytest.mark.parametrize("tail, plain", [(1.0, True), (-1.0, False), (np.nan, False), (0.0, False)])
def test_watch_block_books_every_step_or_leaves_them_to_python(tail, plain):
    """blocks.c watch_block: the smallest kept margin of each watched step (NaN without one), the
    running minimum per subsystem and the steps estimated; a failing, NaN or zero margin: 1, nothing
    written."""
    k, count = 2, 9
    certs = np.full((count, 3 * k + 1), np.nan)
    certs[:, k + 1:2 * k + 1] = [[3.0, 2.0]] * count
    certs[:, 2 * k + 1:] = [[1.0, 0.0], [0.0, 0.0], [1.0, 1.0]] * 3
    certs[6, k + 1] = tail
    out, margins = np.full(count, 7.0), (ctypes.c_double * k)(5.0, np.nan)
    call = blocks.WatchBlock(count=count, k=k, first=0, every=3, tol=0.5, certs=certs.ctypes.data, ldc=3 * k + 1,
                             out=out.ctypes.data, min_margin=margins)
    assert blocks.library().watch_block(ctypes.byref(call)) == (not plain)
    if plain:
        assert out.tolist()[::3] == [3.0, 3.0, 1.0] and np.isnan(out[[1, 2, 4, 5, 7, 8]]).all()
        assert margins[0] == 1.0 and np.isnan(margins[1]) and call.probed == 3
    else:
        assert (out == 7.0).all() and margins[0] == 5.0
