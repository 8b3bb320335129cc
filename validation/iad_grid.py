#!/usr/bin/env python3
"""Adding-doubling references (iadpython, S. Prahl) for smooth-boundary slabs.

A slab of optical depth b, single-scattering albedo a and Henyey-Greenstein g, of IOR n, with
air (IOR 1) above and below and no glass slides, lit by a collimated beam at normal incidence.
iadpython's Sample.rt() returns (UR1, UT1, URU, UTU); UR1 and UT1 are the total reflected and
transmitted fractions for collimated normal incidence, specular reflection and unscattered
transmission included: strata's directional albedo R and T at theta = 0 (delta lobes included).
(Checked: with a = 0 they equal the closed form of a Fresnel slab with an absorber.)

The quadrature error is estimated as |value(N) - value(N/2)|. iadpython applies the delta-M
truncation of the phase function to N terms, which the same difference also covers. N is 24
for n = 1 (one Radau rule on [0, 1]) and 48 otherwise (Gauss on [0, nu_c] and Radau on [nu_c, 1],
24 points each): iadpython 0.5.3's Radau rule loses accuracy above 24 points (its weights sum to
1 - 3.5e-5 at 32 points and fail completely at 64, where UR1 drops from 0.645 to 0.103 for
a = 0.99, b = 4, g = 0, n = 1), so larger N would be worse, not better. Usage: iad_grid.py [--out validation/references/iad.csv]
"""
import argparse
import itertools
import json
import os
import platform
import sys
import time

import numpy as np
import iadpython

HERE = os.path.dirname(os.path.abspath(__file__))

TAUS = [0.25, 1.0, 4.0]
ALBEDOS = [0.5, 0.9, 0.99]
GS = [-0.5, 0.0, 0.5, 0.9]
IORS = [1.0, 1.33, 1.5]


def rt(a, b, g, n, q):
    s = iadpython.Sample(a=a, b=b, g=g, d=1.0, n=n, n_above=1.0, n_below=1.0, quad_pts=q)
    ur1, ut1, _uru, _utu = s.rt()
    return float(ur1), float(ut1)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default=os.path.join(HERE, "references", "iad.csv"))
    args = ap.parse_args()
    t0 = time.time()
    rows = []
    for n, b, a, g in itertools.product(IORS, TAUS, ALBEDOS, GS):
        nq = 24 if n == 1.0 else 48
        r, t = rt(a, b, g, n, nq)
        r2, t2 = rt(a, b, g, n, nq // 2)
        rows.append((n, b, a, g, r, t, abs(r - r2), abs(t - t2)))
    dt = time.time() - t0
    with open(args.out, "w") as f:
        f.write("ior,tau,albedo,g,R,T,quad_err_R,quad_err_T\n")
        for row in rows:
            f.write(",".join(repr(float(x)) for x in row) + "\n")
    meta = {"tool": "iadpython", "iadpython": iadpython.__version__, "numpy": np.__version__,
            "python": platform.python_version(), "command": " ".join(["python3"] + sys.argv),
            "quadrature_points": "N = 24 for n = 1, 48 otherwise",
            "quad_err": "|value(N) - value(N/2)|",
            "radau_defect": "iadpython 0.5.3 radau(n) weights sum to 1 - 3.5e-5 at n = 32; fails at 64",
            "quantity": "UR1, UT1 of Sample(a, b, g, d=1, n, n_above=1, n_below=1).rt(): normal incidence",
            "seconds": round(dt, 1)}
    with open(os.path.splitext(args.out)[0] + ".json", "w") as f:
        json.dump(meta, f, indent=1)
    print(f"{len(rows)} rows in {dt:.1f} s; max quad err R {max(r[6] for r in rows):.2e} "
          f"T {max(r[7] for r in rows):.2e}")


if __name__ == "__main__":
    main()
