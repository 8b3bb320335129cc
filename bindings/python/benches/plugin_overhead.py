"""The Mitsuba plugin's overhead: one scene rendered with the strata plugin
and with Mitsuba's built-in BSDF of the same physics, in turns.

    target/venv/bin/python bindings/python/benches/plugin_overhead.py [--repeat 5] [--profile]

The scene is the one of bindings/python/tests/test_mitsuba.py (a sphere under
a constant environment and a sun, path tracer of depth 8, box filter): the
strata one-interface rough dielectric (GGX, α 0.3, ior 1.5, separable
shadowing) with the plugin's defaults (1 walk per eval, seed 0, the
library's pdf) against Mitsuba's ``roughdielectric`` (GGX, α 0.3,
``int_ior`` 1.5, ``ext_ior`` 1.0). In llvm_ad_rgb both render in Dr.Jit's
evaluated mode (the mode a Python BSDF needs), 61×47 px, 64 spp; in
scalar_rgb (``--scalar-size``, ``--scalar-spp``; 0 skips it) a smaller
image, every call one query.

After a warm-up render of each (which compiles the kernels), ``--repeat``
renders of each alternate (strata, built-in, strata, ...; render r of both
with seed r), and the report gives per render the median and the best wall
time and the median CPU time of the process (all threads: Dr.Jit's and
strata's pools), the ratio of the medians, and the image means over the
repeats with their standard errors (from the per-pixel spread of the renders,
as the tests estimate it), so the reader sees that both draw the same image.
Then where the plugin's time goes, from ``strata_bsdf.mitsuba.stats``: the
time inside the compiled module's batch calls, the rest of the plugin's
methods (Dr.Jit <-> numpy conversion, validity masks, key hashing, building
the results) and the render outside the plugin (Mitsuba). ``--profile``
adds a cProfile of one strata render (the plugin's functions and the
calls they make, by own time).

``--check`` asserts that the image means agree within 5 combined standard
errors (never a time). Timings are noisy on a shared machine: compare the
ratio within one run.
"""

import argparse
import cProfile
import math
import pathlib
import pstats
import statistics
import sys
import tempfile
import time

import drjit as dr
import mitsuba as mi
import numpy as np

GLASS = '[[layers]]\ninterface = { kind = "dielectric", ior = 1.5, roughness = 0.3, shadowing = "separable" }\n'
BUILTIN = {"type": "roughdielectric", "distribution": "ggx", "alpha": 0.3, "int_ior": 1.5, "ext_ior": 1.0}
Z_MAX = 5.0


def rgb(v):
    return {"type": "rgb", "value": v}


def scene(bsdf, width, height, spp):
    """test_mitsuba.py's scene."""
    return mi.load_dict(
        {
            "type": "scene",
            "integrator": {"type": "path", "max_depth": 8},
            "sensor": {
                "type": "perspective",
                "fov": 28,
                "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 5], target=[0, 0, 0], up=[0, 1, 0]),
                "film": {"type": "hdrfilm", "width": width, "height": height, "rfilter": {"type": "box"}},
                "sampler": {"type": "independent", "sample_count": spp},
            },
            "env": {"type": "constant", "radiance": rgb([0.3, 0.35, 0.4])},
            "sun": {"type": "directional", "direction": [-1, -1, -1], "irradiance": rgb([3.0, 3.0, 3.0])},
            "sphere": {"type": "sphere", "bsdf": bsdf},
        }
    )


def render(s, seed):
    """One render as a numpy image, its wall and CPU seconds."""
    t, c = time.perf_counter(), time.process_time()
    img = mi.render(s, seed=seed)
    dr.eval(img)
    a = np.array(img, dtype=np.float64)
    return a, time.perf_counter() - t, time.process_time() - c


def mean_se(imgs):
    """The image mean over K renders and its standard error (the per-pixel
    sample variances over the K renders, summed, over n_px^2 K)."""
    k = imgs.shape[0]
    n_px = imgs[0].size
    return imgs.mean(), math.sqrt(imgs.var(axis=0, ddof=1).sum() / (n_px * n_px * k))


def run_variant(variant, width, height, spp, repeat, material, profile):
    mi.set_variant(variant)
    import strata_bsdf.mitsuba as sm

    sm.register()
    if not variant.startswith("scalar"):
        sm.enable_evaluated_mode()
    scenes = {
        "strata": scene({"type": "strata", "filename": material}, width, height, spp),
        "built-in": scene(BUILTIN, width, height, spp),
    }
    for s in scenes.values():
        render(s, 1000)  # warm-up: compiles the kernels
    res = {name: {"img": [], "wall": [], "cpu": [], "stats": []} for name in scenes}
    for r in range(repeat):
        for name, s in scenes.items():
            sm.reset_stats()
            img, wall, cpu = render(s, r)
            out = res[name]
            out["img"].append(img)
            out["wall"].append(wall)
            out["cpu"].append(cpu)
            out["stats"].append({k: dict(v) for k, v in sm.stats.items()})

    print(f"## {variant}, {width}x{height} px, {spp} spp, path depth 8, {repeat} renders each "
          f"(in turns, after a warm-up render)\n")
    print("| BSDF | wall (s), median | wall (s), best | CPU (s), median | image mean ± standard error |")
    print("|---|---|---|---|---|")
    means = {}
    for name, out in res.items():
        m, se = mean_se(np.stack(out["img"]))
        means[name] = (m, se)
        print(f"| {name} | {statistics.median(out['wall']):.3f} | {min(out['wall']):.3f} | "
              f"{statistics.median(out['cpu']):.3f} | {m:.5f} ± {se:.5f} |")
    ws, wb = (statistics.median(res[n]["wall"]) for n in scenes)
    cs, cb = (statistics.median(res[n]["cpu"]) for n in scenes)
    (ms, ses), (mb, seb) = means["strata"], means["built-in"]
    z = (ms - mb) / math.hypot(ses, seb)
    print(f"\nstrata / built-in: wall {ws / wb:.2f}x (best {min(res['strata']['wall']) / min(res['built-in']['wall']):.2f}x), "
          f"CPU {cs / cb:.2f}x; image means differ by {100 * (ms / mb - 1):+.2f} % (z {z:+.2f})\n")

    # Where a strata render's time goes: the stats of its median render
    # (the lower of the two middle ones for an even count).
    walls = res["strata"]["wall"]
    i = sorted(range(len(walls)), key=walls.__getitem__)[(len(walls) - 1) // 2]
    st, wall = res["strata"]["stats"][i], res["strata"]["wall"][i]
    print("| plugin method | calls | queries | in the method (s) | in strata's batch calls (s) | "
          "plugin glue (s) | glue per call (ms) |")
    print("|---|---|---|---|---|---|---|")
    tot = {"calls": 0, "queries": 0, "seconds": 0.0, "strata_seconds": 0.0}
    for meth, s in st.items():
        if not s["calls"]:
            continue
        for k in tot:
            tot[k] += s[k]
        glue = s["seconds"] - s["strata_seconds"]
        print(f"| {meth} | {s['calls']} | {s['queries']} | {s['seconds']:.3f} | {s['strata_seconds']:.3f} | "
              f"{glue:.3f} | {1e3 * glue / s['calls']:.3f} |")
    glue = tot["seconds"] - tot["strata_seconds"]
    print(f"| all | {tot['calls']} | {tot['queries']} | {tot['seconds']:.3f} | {tot['strata_seconds']:.3f} | "
          f"{glue:.3f} | {1e3 * glue / max(tot['calls'], 1):.3f} |")
    outside = wall - tot["seconds"]
    print(f"\nstrata render of {wall:.3f} s: {tot['strata_seconds']:.3f} s in strata's batch calls "
          f"({100 * tot['strata_seconds'] / wall:.0f} %), {glue:.3f} s plugin glue ({100 * glue / wall:.0f} %), "
          f"{outside:.3f} s outside the plugin ({100 * outside / wall:.0f} %; the built-in render: {wb:.3f} s)\n")

    if profile:
        sm.reset_stats()
        prof = cProfile.Profile()
        prof.enable()
        mi.render(scenes["strata"], seed=0)
        prof.disable()
        print(f"cProfile of one {variant} strata render (functions by own time, top 15):\n```")
        pstats.Stats(prof, stream=sys.stdout).sort_stats("tottime").print_stats(15)
        print("```\n")
    return z


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--width", type=int, default=61)
    ap.add_argument("--height", type=int, default=47)
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--scalar-size", type=int, nargs=2, default=[23, 15], metavar=("W", "H"))
    ap.add_argument("--scalar-spp", type=int, default=16, help="0 skips scalar_rgb")
    ap.add_argument("--profile", action="store_true", help="add a cProfile of one strata render")
    ap.add_argument("--check", action="store_true", help="assert the image means agree within 5 standard errors")
    args = ap.parse_args()
    if args.repeat < 2:
        ap.error("--repeat must be at least 2 (the standard errors need two renders)")

    with tempfile.TemporaryDirectory() as d:
        material = str(pathlib.Path(d) / "rough_glass.toml")
        pathlib.Path(material).write_text(GLASS)
        zs = [run_variant("llvm_ad_rgb", args.width, args.height, args.spp, args.repeat, material, args.profile)]
        if args.scalar_spp > 0:
            w, h = args.scalar_size
            zs.append(run_variant("scalar_rgb", w, h, args.scalar_spp, args.repeat, material, args.profile))
    if args.check:
        assert all(abs(z) < Z_MAX for z in zs), f"image means differ by more than {Z_MAX} standard errors: z {zs}"
        print(f"check: image means agree within {Z_MAX} standard errors")


if __name__ == "__main__":
    main()
