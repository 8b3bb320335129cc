"""Where the bidirectional estimator stops paying: its efficiency over the
unidirectional one's, for one-walk evals (a renderer's call), against the
optical depth of the scattering layer of three three-interface stacks
(examples/materials/paper/{logo_drop, two_faced_slab, ceramics}.toml, the
layer's sigma_t replaced). Efficiency is 1 / (variance × CPU time) of one
eval at each of three direction pairs; 40,000 unidirectional and 3,000
bidirectional walks per pair (a heavy tail's variance is underestimated
from few samples, which favours the unidirectional side). Needs the Python
module (bindings/python). docs/results.md, *The optical depth threshold*,
has its output.

    python benches/bidir_depth.py [logo_drop,two_faced_slab,ceramics]
"""
import sys
import time

import numpy as np
import strata_bsdf as sb

LAYER = {"logo_drop": "sigma_t = 3.0", "two_faced_slab": "sigma_t = 1.5,", "ceramics": "sigma_t = 12.0"}
DEPTHS = [0.5, 1, 2, 3, 4, 6, 8, 12]
# (θi, φi, θo, φo) in radians.
PAIRS = [(0.698, 0.0, 0.524, 2.976), (0.3, 0.0, 1.1, 3.0), (1.2, 0.0, 0.9, 1.0)]


def directions(theta, phi, n):
    d = [np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)]
    return np.tile(d, (n, 1)).astype(np.float32)


def efficiency(toml, estimator, pair, n):
    b = sb.Bsdf.from_toml(toml, seed=1).configure(f"threads=1 estimator={estimator}")
    keys = np.random.default_rng(0).integers(0, 2**63, n, dtype=np.uint64)
    wi, wo = directions(pair[0], pair[1], n), directions(pair[2], pair[3], n)
    t0 = time.process_time()
    f, _ = b.eval(wi, wo, keys)
    seconds = (time.process_time() - t0) / n
    return 1.0 / (f.mean(1).astype(np.float64).var() * seconds + 1e-300)


def main():
    names = sys.argv[1].split(",") if len(sys.argv) > 1 else list(LAYER)
    for name in names:
        text = open(f"examples/materials/paper/{name}.toml").read()
        for depth in DEPTHS:
            toml = text.replace(LAYER[name], LAYER[name].replace(LAYER[name].split()[-1].rstrip(","), str(depth)))
            ratios = [efficiency(toml, "bidir", p, 3000) / efficiency(toml, "uni", p, 40000) for p in PAIRS]
            print(f"{name:15s} depth {depth:5.1f}: bidir / uni " + " ".join(f"{r:8.2f}" for r in ratios), flush=True)


if __name__ == "__main__":
    main()
