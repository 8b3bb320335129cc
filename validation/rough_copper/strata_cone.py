#!/usr/bin/env python3
"""strata's value over the same cone as slab_cu.py: N directions w uniform (in solid angle) in the
cone of half-angle delta around wi = (sin ti, 0, cos ti), wo = (sin to cos po, sin to sin po, cos to);
I = Omega * mean(f(w, wo) cos theta_w); f_mean = I / (Omega cos ti); sigma from the spread (includes
strata's own MC noise). Also the point value f(wi, wo) with many samples.
Usage: strata_cone.py MATERIAL TI TO PO DELTA [N] [SAMPLES_PER_DIR] [POINT_SAMPLES]"""
import sys, json, math, subprocess
import numpy as np
import os
STRATA = os.environ.get("STRATA", "target/release/strata")

def d(t, p):
    t, p = math.radians(t), math.radians(p)
    return np.array([math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t)])

def ev(mat, pairs, samples, seed=0):
    inp = "".join(json.dumps({"wi": list(map(float, a)), "wo": list(map(float, b))}) + "\n" for a, b in pairs)
    out = subprocess.run([STRATA, "eval", "--material", mat, "--samples", str(samples), "--estimator", "uni",
                          "--seed", str(seed), "--threads", "1"], input=inp, capture_output=True, text=True, check=True).stdout
    return [json.loads(l) for l in out.splitlines() if l.strip()]

def main():
    mat, ti, to, po, delta = sys.argv[1], *map(float, sys.argv[2:6])
    N = int(sys.argv[6]) if len(sys.argv) > 6 else 2000
    S = int(sys.argv[7]) if len(sys.argv) > 7 else 20000
    P = int(sys.argv[8]) if len(sys.argv) > 8 else 4000000
    rng = np.random.default_rng(12345)
    wi = d(ti, 0.0); wo = d(to, po)
    # frame around wi
    t1 = np.cross(wi, [0, 1, 0] if abs(wi[1]) < 0.9 else [1, 0, 0]); t1 /= np.linalg.norm(t1)
    t2 = np.cross(wi, t1)
    cd = math.cos(math.radians(delta))
    u = rng.random(N); v = rng.random(N)
    ct = 1 - u * (1 - cd); st = np.sqrt(1 - ct * ct); ph = 2 * math.pi * v
    ws = (ct[:, None] * wi + (st * np.cos(ph))[:, None] * t1 + (st * np.sin(ph))[:, None] * t2)
    # strata reuses the same random streams for every query of one invocation (same seed), so the
    # directions of one invocation share their MC noise: B batches with different seeds, sigma
    # from the spread of the batch means.
    B = 40
    bm = []
    for b, idx in enumerate(np.array_split(np.arange(N), B)):
        res = ev(mat, [(w, wo) for w in ws[idx]], S, seed=1000 + b)
        bm.append(np.mean(np.array([r["f"][0] for r in res]) * ws[idx, 2]))
    bm = np.array(bm)
    omega = 2 * math.pi * (1 - cd)
    I = omega * bm.mean(); sI = omega * bm.std(ddof=1) / math.sqrt(B)
    norm = omega * math.cos(math.radians(ti))
    pt = ev(mat, [(wi, wo)], P, seed=3)[0]
    print(json.dumps({"material": mat, "ti": ti, "to": to, "po": po, "delta": delta, "N": N, "S": S, "batches": B,
                      "I": I, "sigma_I": sI, "f_mean": I / norm, "sigma_f": sI / norm,
                      "point_f": pt["f"][0], "point_sigma": pt["stderr"][0], "point_samples": P}), flush=True)

main()
