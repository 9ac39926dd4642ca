"""The figure of the scenes beyond the benchmark, docs/figures/scenes.png (about 30 s; `make figures`).

    .venv/bin/python scripts/scene_figure.py

(a) configs/chain.yaml: the displacement of each of the 8 masses (offset by its index) after a
    hammer blow on mass 0, for DR with K = 0 and K = 3 against the monolithic reference.
(b) every scene: max error against its monolithic reference versus the inner budget K.
"""
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from wavecosim.scenario.config import load_scenario  # noqa: E402
from wavecosim.run.runner import run  # noqa: E402
from wavecosim.sweeps.budget import reference_run  # noqa: E402

SCENES = ("chain", "star", "planar", "rlc_motor")
KS = (0, 1, 2, 3, 5, 10, 20, 30, 50, 100)
FLOOR = 1e-16


def main():
    fig, (ax_chain, ax_err) = plt.subplots(1, 2, figsize=(11, 4.6), gridspec_kw={"width_ratios": [1.2, 1]})
    chain = load_scenario(ROOT / "configs" / "chain.yaml")
    reference = reference_run(chain)
    styles = {0: ("tab:red", "DR, K = 0"), 3: ("tab:blue", "DR, K = 3")}
    spacing = 0.25
    for K, (color, label) in styles.items():
        result = run(chain.with_master(algorithm="dr", K=K), certificates=False)
        for i, col in enumerate(chain.error):
            ax_chain.plot(result.t, result.column(col) + spacing * i, color=color, lw=1.2,
                          label=label if i == 0 else None)
    for i, col in enumerate(chain.error):
        ax_chain.plot(reference.t, reference.column(col) + spacing * i, "k--", lw=1.0,
                      label="monolithic" if i == 0 else None)
    ax_chain.set_yticks([spacing * i for i in range(len(chain.error))], [f"q{i}" for i in range(len(chain.error))])
    ax_chain.set_xlabel("t (s)")
    ax_chain.set_ylabel(f"mass displacement, offset by {spacing} m per mass")
    ax_chain.set_title("(a) chain: 8 FMUs, hammer blow on mass 0, wall after mass 7")
    ax_chain.legend(loc="upper left", fontsize=8)
    ax_chain.grid(alpha=0.3)

    for name in SCENES:
        sc = load_scenario(ROOT / "configs" / f"{name}.yaml")
        ref = reference_run(sc)
        errors = [run(sc.with_master(algorithm="dr", K=K), certificates=False, reference=ref).summary["max_error"]
                  for K in KS]
        ax_err.semilogy(KS, np.maximum(errors, FLOOR), "o-", ms=4, label=f"{name} (T = {sc.T:g} s)")
        print(name, " ".join(f"K{K}:{e:.1e}" for K, e in zip(KS, errors)))
    ax_err.set_xlabel("inner budget K")
    ax_err.set_ylabel("max error vs monolithic reference")
    ax_err.set_title("(b) every scene: DR error falls as K grows")
    ax_err.legend(fontsize=8)
    ax_err.grid(alpha=0.3, which="both")

    out = ROOT / "docs" / "figures" / "scenes.png"
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(out, dpi=130)
    print(f"wrote {out.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
