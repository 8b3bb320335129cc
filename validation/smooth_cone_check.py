#!/usr/bin/env python3
"""128 more Mitsuba runs (seeds 90000+) of the two cone values of smooth_slab_oblique, whose 16-run
references sat 2.4 and 2.0 sigma above strata (docs/validation.md). About 9 minutes.
Prints: query, mean, sigma, seconds. Run from the repository root."""
import sys, math, time
sys.path.insert(0, "validation")
import mitsuba_slab as ms, numpy as np, drjit as dr
dr.set_thread_count(1)
case = ms.EXTRA["smooth_slab_oblique"]
for q in [("f", 30.0, 50.0, 90.0, 5.0), ("f", 30.0, 140.0, 0.0, 5.0)]:
    t=time.time()
    sc = ms.scene_for(case, q)
    m = np.array([ms.run_once(sc, q, 1 << 20, 90000 + k, -1.0)[0][0] for k in range(128)])
    print(q, m.mean(), m.std(ddof=1) / math.sqrt(128), time.time()-t, flush=True)
