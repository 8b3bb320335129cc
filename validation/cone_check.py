#!/usr/bin/env python3
"""A 256-run Mitsuba measurement of the two cone values of smooth_coat_lambertian (closed form known),
to test whether the cone measurement has a systematic (docs/validation.md). About 8 minutes.
Prints: query, mean per channel, sigma per channel, seconds. Run from the repository root."""
import sys, time
sys.path.insert(0, "validation")
import mitsuba_slab as ms, numpy as np, drjit as dr
dr.set_thread_count(1)
case = ms.CASES["smooth_coat_lambertian"]
for q in [("f", 60.0, 10.0, 0.0, 4.0), ("f", 20.0, 50.0, 90.0, 4.0)]:
    t=time.time()
    sc = ms.scene_for(case, q)
    m = np.array([ms.run_once(sc, q, 1 << 20, 70000 + k, -1.0)[0] for k in range(256)])
    print(q, m.mean(0).tolist(), (m.std(0, ddof=1) / 16).tolist(), time.time()-t, flush=True)
