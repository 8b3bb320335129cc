#!/usr/bin/env python3
"""Reference values for layered stacks by volumetric path tracing of the explicit slab
in Mitsuba 3.9.1 (the paper's Fig. 2 method), independent of strata's code.

The slab is two rectangles W = 2e4 wide, 1 apart (thickness 1), carrying Mitsuba's own
BSDFs (dielectric, roughdielectric ggx, roughconductor, diffuse); a homogeneous medium with an
hg phase fills the gap where the stack has one (optical depth = sigma_t * 1). Exteriors have
IOR 1.0 exactly (Mitsuba's ext_ior default 1.000277 is overridden).

Two measurements, both by camera rays handed to the volpath integrator directly (no film: a
radiancemeter film accumulates in float32); each run's mean is taken in float64 and the
reference is the mean of K independent runs (different sampler seeds) with sigma = std / sqrt(K).

* Directional albedo R(wi) or T(wi): a constant environment of radiance 1 and a black blocker
  (a 2e6-wide rectangle, reflectance 0) 0.5 below the slab (R) or above it (T). By reciprocity
  (exteriors of equal IOR) the radiance seen along wi equals R(wi) (or T(wi)).
* BSDF value: a disk light of radiance 1 at distance D = 1e4 in direction wi, of angular radius
  delta; the radiance seen along wo is the cone integral  I = int_cone f(w, wo) cos(theta_w) dw.
  The comparison computes strata's I over the same cone (uniform directions in the cone), so
  there is no cone-averaging bias; the table also shows I / (Omega cos theta_i).

Usage: mitsuba_slab.py [--runs K] [--rays N] [--only CASE] [--out validation/references/mitsuba.csv]
"""
import argparse
import json
import math
import os
import platform
import sys
import time

import numpy as np
import mitsuba as mi
import drjit as dr

mi.set_variant("llvm_ad_rgb")

HERE = os.path.dirname(os.path.abspath(__file__))
W = 2.0e4  # half-width of the slab's rectangles
THICK = 1.0
D_LIGHT = 1.0e4


def rgb(v):
    v = v if isinstance(v, (list, tuple)) else [v, v, v]
    return {"type": "rgb", "value": [float(x) for x in v]}


def rough_dielectric(int_ior, ext_ior, alpha, distribution="ggx"):
    if alpha == 0:
        return {"type": "dielectric", "int_ior": int_ior, "ext_ior": ext_ior}
    return {
        "type": "roughdielectric",
        "distribution": distribution,
        "alpha": alpha,
        "int_ior": int_ior,
        "ext_ior": ext_ior,
        "sample_visible": True,
    }


def rough_conductor(eta, k, alpha, distribution="ggx"):
    return {
        "type": "roughconductor",
        "distribution": distribution,
        "alpha": alpha,
        "eta": rgb(eta),
        "k": rgb(k),
        "sample_visible": True,
    }


# The copper of the materials here, relative to vacuum: strata's Cu preset before issue 42
# (now written out in validation/materials/*.toml, where the preset is measured spectra).
CU_ETA = [0.200438, 0.924033, 1.10221]
CU_K = [3.91295, 2.45285, 2.14219]


# Each case: the top interface, an optional medium, the bottom interface (Mitsuba dicts), the
# strata material file, whether it transmits, and the queries:
#   ("R", theta_i) / ("T", theta_i)  albedos (phi_i = 0)
#   ("f", theta_i, theta_o, phi_o, delta_deg)  cone integral, phi_i = 0; theta_o > 90 is below.
CASES = {
    # A check of the measurement itself: this stack has a closed form (docs/validation.md).
    "smooth_coat_lambertian": dict(
        material="smooth_coat_lambertian.toml",
        top=rough_dielectric(1.5, 1.0, 0.0),
        medium=None,
        bottom={"type": "diffuse", "reflectance": rgb([0.0, 0.5, 1.0])},
        queries=[("R", 0.0), ("R", 70.0), ("f", 20.0, 50.0, 90.0, 4.0), ("f", 60.0, 10.0, 0.0, 4.0)],
    ),
    "rough_coat_lambertian": dict(
        material="rough_coat_lambertian.toml",
        top=rough_dielectric(1.5, 1.0, 0.3),
        medium=None,
        bottom={"type": "diffuse", "reflectance": rgb([0.2, 0.5, 0.8])},
        queries=[("R", 0.0), ("R", 60.0), ("f", 30.0, 30.0, 180.0, 4.0),
                 ("f", 0.0, 45.0, 90.0, 4.0), ("f", 60.0, 20.0, 0.0, 4.0)],
    ),
    "rough_coat_medium_lambertian": dict(
        material="rough_coat_medium_lambertian.toml",
        top=rough_dielectric(1.5, 1.0, 0.2),
        medium=dict(sigma_t=[0.5, 1.0, 2.0], albedo=0.8, g=0.6),
        bottom={"type": "diffuse", "reflectance": rgb(0.7)},
        queries=[("R", 0.0), ("R", 45.0), ("f", 20.0, 20.0, 180.0, 4.0),
                 ("f", 45.0, 30.0, 90.0, 4.0)],
    ),
    "smooth_coat_absorber_copper": dict(
        material="smooth_coat_absorber_copper.toml",
        top=rough_dielectric(1.5, 1.0, 0.0),
        medium=dict(sigma_t=[0.1, 0.3, 0.6], albedo=0.0, g=0.0),
        bottom=rough_conductor([e / 1.5 for e in CU_ETA], [k / 1.5 for k in CU_K], 0.25),
        queries=[("R", 0.0), ("R", 50.0), ("f", 30.0, 40.0, 90.0, 5.0),
                 ("f", 10.0, 50.0, 0.0, 5.0)],
    ),
    "rough_slab_transmissive": dict(
        material="rough_slab_transmissive.toml",
        top=rough_dielectric(1.5, 1.0, 0.3),
        medium=dict(sigma_t=0.5, albedo=0.9, g=0.3),
        bottom=rough_dielectric(1.0, 1.5, 0.2),  # normal +z: ext = slab (1.5), int = below (1.0)
        queries=[("R", 0.0), ("T", 0.0), ("R", 60.0), ("T", 60.0),
                 ("f", 30.0, 40.0, 180.0, 4.0), ("f", 30.0, 150.0, 180.0, 4.0),
                 ("f", 0.0, 120.0, 90.0, 4.0)],
    ),
    "three_interfaces": dict(
        material="three_interfaces_mitsuba.toml",
        interfaces=[rough_dielectric(1.5, 1.0, 0.15),
                    rough_dielectric(1.2, 1.5, 0.25),
                    {"type": "diffuse", "reflectance": rgb([0.8, 0.6, 0.3])}],
        media=[dict(sigma_t=[0.3, 0.6, 0.9], albedo=0.0, g=0.0),
               dict(sigma_t=1.0, albedo=0.9, g=-0.3)],
        queries=[("R", 0.0), ("R", 45.0), ("f", 30.0, 30.0, 180.0, 4.0), ("f", 0.0, 60.0, 90.0, 4.0)],
    ),
}

# Run separately (--only paper_validation1 --out references/mitsuba_validation1.csv): the
# paper's Fig. 2 "Validation 1" stack, Beckmann, with copper relative to the coat.
EXTRA = {
    # Run separately (--only smooth_slab_oblique --out references/mitsuba_smooth.csv): a
    # scattering slab between smooth boundaries at oblique incidence, which iadpython cannot do
    # (its normal-incidence values of the same slab are in iad.csv: a three-way check).
    "smooth_slab_oblique": dict(
        material="smooth_slab_oblique.toml",
        top=rough_dielectric(1.5, 1.0, 0.0),
        medium=dict(sigma_t=1.0, albedo=0.9, g=0.5),
        bottom=rough_dielectric(1.0, 1.5, 0.0),
        queries=[("R", 0.0), ("T", 0.0), ("R", 40.0), ("T", 40.0), ("R", 70.0), ("T", 70.0),
                 ("f", 30.0, 50.0, 90.0, 5.0), ("f", 30.0, 140.0, 0.0, 5.0)],
    ),
    # Run separately (--only slab_over_glass --out references/mitsuba_glass.csv): exteriors of
    # different IOR (air above, glass 1.5 below), so transmitted radiance carries strata's n²
    # factor; the transmitted values are measured directly (light above, camera in the glass),
    # not by reciprocity. No T albedo (reciprocity would need the n² factor too).
    "slab_over_glass": dict(
        material="slab_over_glass.toml",
        top=rough_dielectric(1.33, 1.0, 0.25),
        medium=dict(sigma_t=0.8, albedo=0.85, g=0.4),
        bottom=rough_dielectric(1.5, 1.33, 0.2),  # normal +z: ext = slab (1.33), int = glass 1.5
        queries=[("R", 0.0), ("R", 50.0), ("f", 30.0, 160.0, 180.0, 4.0),
                 ("f", 0.0, 140.0, 90.0, 4.0), ("f", 45.0, 120.0, 0.0, 4.0)],
    ),
    # Run separately (--only rough_slab_from_below --out references/mitsuba_below.csv): the
    # transmissive slab lit from below (theta_i > 90), reflected and transmitted.
    "rough_slab_from_below": dict(
        material="rough_slab_transmissive.toml",
        top=rough_dielectric(1.5, 1.0, 0.3),
        medium=dict(sigma_t=0.5, albedo=0.9, g=0.3),
        bottom=rough_dielectric(1.0, 1.5, 0.2),
        queries=[("R", 180.0), ("T", 180.0), ("R", 130.0), ("T", 130.0),
                 ("f", 150.0, 140.0, 180.0, 4.0), ("f", 150.0, 40.0, 0.0, 4.0),
                 ("f", 180.0, 60.0, 90.0, 4.0)],
    ),
    "paper_validation1": dict(
        material="paper_validation1.toml",
        top=rough_dielectric(1.5, 1.0, 0.05, "beckmann"),
        medium=dict(sigma_t=1.0, albedo=[0.5, 0.7, 0.95], g=0.5),
        bottom=rough_conductor([e / 1.5 for e in CU_ETA], [k / 1.5 for k in CU_K], 0.05, "beckmann"),
        queries=[("R", 0.0), ("R", 45.0), ("f", 30.0, 30.0, 180.0, 4.0), ("f", 0.0, 45.0, 90.0, 4.0)],
    ),
}


def chromatic(case):
    return any(m is not None and (isinstance(m["sigma_t"], list) or isinstance(m["albedo"], list))
               for m in interfaces_of(case)[1])


def medium_dict(m, channel=None):
    st = m["sigma_t"] if isinstance(m["sigma_t"], list) else [m["sigma_t"]] * 3
    al = m["albedo"] if isinstance(m["albedo"], list) else [m["albedo"]] * 3
    if channel is not None:  # a grey medium with one channel's coefficients
        st, al = [st[channel]] * 3, [al[channel]] * 3
    smax = max(st)  # an rgb value is parsed as a reflectance (<= 1): normalise, then scale
    return {"type": "homogeneous", "sigma_t": rgb([x / smax for x in st]), "scale": smax,
            "albedo": rgb(al), "phase": {"type": "hg", "g": m["g"]}}


def interfaces_of(case):
    """(bsdfs top to bottom, media between them): two-interface cases use top/medium/bottom."""
    if "interfaces" in case:
        return case["interfaces"], case["media"]
    return [case["top"], case["bottom"]], [case["medium"]]


def scene_for(case, query, channel=None):
    kind = query[0]
    d = {"type": "scene", "integrator": {"type": "volpath", "max_depth": -1, "rr_depth": 5}}
    bsdfs, media = interfaces_of(case)
    for i, m in enumerate(media):
        if m is not None:
            d[f"medium_{i}"] = medium_dict(m, channel)
    for i, b in enumerate(bsdfs):
        # rectangle i at z = -i, normal +z: exterior (above) is medium i-1, interior medium i
        shape = {"type": "rectangle", "bsdf": b,
                 "to_world": mi.ScalarTransform4f().translate([0, 0, -i * THICK]).scale([W, W, 1.0])}
        if i > 0 and media[i - 1] is not None:
            shape["exterior"] = {"type": "ref", "id": f"medium_{i - 1}"}
        if i < len(media) and media[i] is not None:
            shape["interior"] = {"type": "ref", "id": f"medium_{i}"}
        d[f"interface_{i}"] = shape
    bottom_z = -(len(bsdfs) - 1) * THICK
    black = {"type": "diffuse", "reflectance": rgb(0.0)}
    if kind in ("R", "T"):
        d["env"] = {"type": "constant", "radiance": rgb(1.0)}
        # block the side the measured light must not come from: below for R from above (and T
        # from below), above for T from above (and R from below)
        from_below = query[1] > 90.0
        z = bottom_z - 0.5 if (kind == "R") != from_below else 0.5
        d["blocker"] = {"type": "rectangle", "bsdf": black,
                        "to_world": mi.ScalarTransform4f().translate([0, 0, z]).scale([1e6, 1e6, 1.0])}
    else:
        _, ti, to, po, delta = query
        wi = direction(ti, 0.0)
        r = D_LIGHT * math.tan(math.radians(delta))
        c = [D_LIGHT * x for x in wi]
        d["light"] = {"type": "disk", "emitter": {"type": "area", "radiance": rgb(1.0)},
                      "bsdf": black,
                      "to_world": mi.ScalarTransform4f().look_at(origin=c, target=[0, 0, 0], up=up_for(wi))
                      @ mi.ScalarTransform4f().scale([r, r, 1.0])}
    return mi.load_dict(d)


def up_for(w):
    return [0, 1, 0] if abs(w[1]) < 0.9 else [1, 0, 0]


def direction(theta, phi):
    t, p = math.radians(theta), math.radians(phi)
    return [math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t)]


def camera_ray(query, n, bottom_z):
    """Rays looking at the slab from the viewer's direction (wi for albedos, wo for f)."""
    kind = query[0]
    w = direction(query[1], 0.0) if kind in ("R", "T") else direction(query[2], query[3])
    base = [0.0, 0.0, 0.0] if w[2] > 0 else [0.0, 0.0, bottom_z]
    o = [base[i] + 0.1 * w[i] for i in range(3)]
    o = mi.Point3f(mi.Float(np.full(n, o[0], np.float32)), mi.Float(np.full(n, o[1], np.float32)),
                   mi.Float(np.full(n, o[2], np.float32)))
    dvec = mi.Vector3f(-w[0], -w[1], -w[2])
    return mi.Ray3f(o, dr.normalize(dvec + mi.Vector3f(0.0)))


def run_once(scene, query, n, seed, bottom_z):
    sampler = mi.load_dict({"type": "independent"})
    sampler.seed(seed, n)
    ray = camera_ray(query, n, bottom_z)
    spec, _valid, _aov = scene.integrator().sample(scene, sampler, ray, None, True)
    dr.eval(spec)
    out = np.stack([np.asarray(spec[i].numpy(), dtype=np.float64) for i in range(3)])
    return out.mean(axis=1), out.var(axis=1, ddof=1)


def cone_solid_angle(delta):
    return 2.0 * math.pi * (1.0 - math.cos(math.radians(delta)))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=16)
    ap.add_argument("--rays", type=int, default=1 << 20)
    ap.add_argument("--only", default=None)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--out", default=os.path.join(HERE, "references", "mitsuba.csv"))
    args = ap.parse_args()
    dr.set_thread_count(args.threads)
    rows = []
    meta = {"tool": "mitsuba", "mitsuba": mi.__version__, "drjit": dr.__version__,
            "variant": mi.variant(), "python": platform.python_version(),
            "command": " ".join(["python3"] + sys.argv), "runs": args.runs, "rays_per_run": args.rays,
            "seeds": "run k uses sampler seed 1000 * case_index + 100 * query_index + k "
                     "(+ 10000 * channel for a chromatic case, one grey run per channel)",
            "geometry": {"half_width": W, "thickness": THICK, "light_distance": D_LIGHT},
            "cases": {}}
    t_all = time.time()
    cases = dict(CASES, **EXTRA) if args.only in EXTRA else CASES
    for ci, (name, case) in enumerate(cases.items()):
        if args.only and name != args.only:
            continue
        meta["cases"][name] = {"material": case["material"]}
        for qi, q in enumerate(case["queries"]):
            t0 = time.time()
            bottom_z = -(len(interfaces_of(case)[0]) - 1) * THICK
            if chromatic(case):
                # volpath in RGB mode samples distances with one random channel and weights the
                # others by the ratio of densities, not by spectral MIS: for a channel with
                # sigma_t below half another's the weights are heavy-tailed (a first run gave red
                # 1 % low at 2.3 and 3.9 of its sigma; references/mitsuba_first_run_rgb_media.log).
                # So each channel c comes from its own run with grey media of channel c.
                means = np.zeros((args.runs, 3))
                for c in range(3):
                    scene = scene_for(case, q, channel=c)
                    for k in range(args.runs):
                        m, _ = run_once(scene, q, args.rays, 1000 * ci + 100 * qi + k + 10000 * c, bottom_z)
                        means[k, c] = m[c]
            else:
                scene = scene_for(case, q)
                means = np.array([run_once(scene, q, args.rays, 1000 * ci + 100 * qi + k, bottom_z)[0]
                                  for k in range(args.runs)])
            ref = means.mean(axis=0)
            sig = means.std(axis=0, ddof=1) / math.sqrt(args.runs)
            dt = time.time() - t0
            if q[0] in ("R", "T"):
                row = dict(case=name, material=case["material"], quantity=q[0], theta_i=q[1], phi_i=0.0,
                           theta_o="", phi_o="", delta_deg="")
            else:
                row = dict(case=name, material=case["material"], quantity="cone", theta_i=q[1], phi_i=0.0,
                           theta_o=q[2], phi_o=q[3], delta_deg=q[4])
            for c in range(3):
                row[f"ref{c}"] = repr(float(ref[c]))
                row[f"sigma{c}"] = repr(float(sig[c]))
            row["seconds"] = f"{dt:.1f}"
            rows.append(row)
            print(name, q, ref, sig, f"{dt:.1f}s", flush=True)
            meta["seconds_total"] = round(time.time() - t_all, 1)
            write(args.out, rows, meta)  # after every query, so a partial run is usable
    meta["seconds_total"] = round(time.time() - t_all, 1)
    write(args.out, rows, meta)


def write(out, rows, meta):
    cols = ["case", "material", "quantity", "theta_i", "phi_i", "theta_o", "phi_o", "delta_deg",
            "ref0", "ref1", "ref2", "sigma0", "sigma1", "sigma2", "seconds"]
    os.makedirs(os.path.dirname(out), exist_ok=True)
    with open(out, "w") as f:
        f.write(",".join(cols) + "\n")
        for r in rows:
            f.write(",".join(str(r[c]) for c in cols) + "\n")
    with open(os.path.splitext(out)[0] + ".json", "w") as f:
        json.dump(meta, f, indent=1)


if __name__ == "__main__":
    main()
