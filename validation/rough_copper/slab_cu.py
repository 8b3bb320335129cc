#!/usr/bin/env python3
"""Brute-force Mitsuba 3.9.1 reference for pbrt-v4's coated_conductor_rough_cu_rough0.1 (first
wavelength): roughdielectric ggx 0.1 (1.0 | 1.5) / absorbing medium, optical depth 0.01 /
roughconductor ggx 0.1 with eta, k RELATIVE to the coat (Mitsuba 3's conductor has no ext_eta:
its Fresnel takes eta + i k as the ratio interior/exterior). Uses the helpers
of validation/mitsuba_slab.py.
Measurement: cone integral I = int_cone f(w, wo) cos(theta_w) dw of a far disk light of angular
radius delta around wi, radiance seen along wo (reciprocity). K runs of N rays, float64 means.
Usage: slab_cu.py THETA_I THETA_O PHI_O DELTA [--runs K] [--rays N] [--seed0 S]"""
import argparse, math, sys, time, json
import numpy as np
import mitsuba as mi
import drjit as dr
mi.set_variant("llvm_ad_rgb")
import os
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
import mitsuba_slab as ms   # only helpers (direction, up_for, camera_ray, run_once)

ETA_REL, K_REL = 0.988815 / 1.5, 2.5792875 / 1.5   # = 0.659210, 1.719525
THICK = 1.0          # gap between the rectangles (lateral extent irrelevant: W = 2e4)
SIGMA_T = 0.01       # optical depth 0.01 = strata's thickness 0.01 * sigma_t 1
W, D_LIGHT = 2.0e4, 1.0e4

def scene(ti, delta):
    top = {"type": "roughdielectric", "distribution": "ggx", "alpha": 0.1,
           "int_ior": 1.5, "ext_ior": 1.0, "sample_visible": True}
    bot = {"type": "roughconductor", "distribution": "ggx", "alpha": 0.1,
           "eta": ETA_REL, "k": K_REL, "sample_visible": True}
    med = {"type": "homogeneous", "sigma_t": SIGMA_T, "albedo": 0.0,
           "phase": {"type": "isotropic"}}
    black = {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0, 0.0, 0.0]}}
    wi = ms.direction(ti, 0.0)
    r = D_LIGHT * math.tan(math.radians(delta))
    c = [D_LIGHT * x for x in wi]
    d = {"type": "scene",
         "integrator": {"type": "volpath", "max_depth": -1, "rr_depth": 5},
         "med": med,
         "top": {"type": "rectangle", "bsdf": top, "interior": {"type": "ref", "id": "med"},
                 "to_world": mi.ScalarTransform4f().scale([W, W, 1.0])},
         "bot": {"type": "rectangle", "bsdf": bot, "exterior": {"type": "ref", "id": "med"},
                 "to_world": mi.ScalarTransform4f().translate([0, 0, -THICK]).scale([W, W, 1.0])},
         "light": {"type": "disk", "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [1.0, 1.0, 1.0]}},
                   "bsdf": black,
                   "to_world": mi.ScalarTransform4f().look_at(origin=c, target=[0, 0, 0], up=ms.up_for(wi))
                   @ mi.ScalarTransform4f().scale([r, r, 1.0])}}
    return mi.load_dict(d)

def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("ti", type=float); ap.add_argument("to", type=float)
    ap.add_argument("po", type=float); ap.add_argument("delta", type=float)
    ap.add_argument("--runs", type=int, default=16)
    ap.add_argument("--rays", type=int, default=1 << 20)
    ap.add_argument("--seed0", type=int, default=5000)
    ap.add_argument("--threads", type=int, default=1)
    a = ap.parse_args()
    dr.set_thread_count(a.threads)
    q = ("f", a.ti, a.to, a.po, a.delta)
    sc = scene(a.ti, a.delta)
    t0 = time.time(); ms_ = []
    for k in range(a.runs):
        m, _ = ms.run_once(sc, q, a.rays, a.seed0 + k, -THICK)
        ms_.append(m[0]); 
        print(f"run {k} I={m[0]:.6e} t={time.time()-t0:.1f}s", file=sys.stderr, flush=True)
    ms_ = np.array(ms_, dtype=np.float64)
    I, sI = ms_.mean(), ms_.std(ddof=1) / math.sqrt(len(ms_))
    omega = 2 * math.pi * (1 - math.cos(math.radians(a.delta)))
    norm = omega * math.cos(math.radians(a.ti))
    print(json.dumps({"ti": a.ti, "to": a.to, "po": a.po, "delta": a.delta, "runs": a.runs, "rays": a.rays,
                      "seed0": a.seed0, "I": I, "sigma_I": sI, "f_mean": I / norm, "sigma_f": sI / norm,
                      "seconds": round(time.time() - t0, 1), "runs_I": ms_.tolist()}), flush=True)

if __name__ == "__main__":
    main()
