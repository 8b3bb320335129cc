"""Measurements for docs/embedding.md: Mitsuba render times with strata
against built-in BSDFs, the share of the render spent inside strata, and the
per-query cost of single calls against one batch through Python.

    python examples/mitsuba/measure.py [--size 256] [--spp 16] [--repeat 3]

Renders run in llvm_ad_rgb in evaluated mode (the mode a Python BSDF needs)
for every BSDF, so the comparison is in the same mode and scene; the
built-in BSDF is also timed in Dr.Jit's default symbolic mode for reference.
Each time is the median of --repeat renders after one warm-up render (which
pays the kernel compilation).
"""

import argparse
import pathlib
import statistics
import sys
import tempfile
import time

import drjit as dr
import mitsuba as mi
import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(pathlib.Path(__file__).parent))

ETA, K = [0.2, 0.92, 1.1], [3.9, 2.45, 2.2]
ONE_INTERFACE = (
    '[[layers]]\ninterface = { kind = "conductor", eta = [0.2, 0.92, 1.1], k = [3.9, 2.45, 2.2], '
    'roughness = 0.3, shadowing = "separable" }\n'
)


def timed_render(scene, repeat, sm=None):
    mi.render(scene, seed=0)  # warm-up: compiles the kernels
    times, inside, module = [], [], []
    for r in range(repeat):
        if sm:
            sm.reset_stats()
        t = time.perf_counter()
        img = mi.render(scene, seed=r + 1)
        dr.eval(img)
        np.array(img)
        times.append(time.perf_counter() - t)
        if sm:
            inside.append(sum(s["seconds"] for s in sm.stats.values()))
            module.append(sum(s["strata_seconds"] for s in sm.stats.values()))
    i = times.index(statistics.median(times))
    calls = sum(s["calls"] for s in sm.stats.values()) if sm else 0
    queries = sum(s["queries"] for s in sm.stats.values()) if sm else 0
    return times[i], (inside[i] if sm else None), (module[i] if sm else None), calls, queries


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--depth", type=int, default=6)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--queries", type=int, default=20000)
    args = ap.parse_args()

    mi.set_variant("llvm_ad_rgb")
    import strata_bsdf
    import strata_bsdf.mitsuba as sm
    from common import scene_dict

    def scene(bsdf):
        return mi.load_dict(scene_dict(mi, bsdf, args.size, args.size, args.spp, args.depth))

    builtin = {"type": "roughconductor", "distribution": "ggx", "alpha": 0.3,
               "eta": {"type": "rgb", "value": ETA}, "k": {"type": "rgb", "value": K}}
    print(f"## Renders: {args.size}x{args.size}, {args.spp} spp, path depth {args.depth}, llvm_ad_rgb\n")
    print("| BSDF | mode | render (s) | in the plugin (s) | in strata's batch calls (s) | share in strata | "
          "plugin calls | queries |")
    print("|---|---|---|---|---|---|---|---|")
    t, *_ = timed_render(scene(builtin), args.repeat)
    print(f"| Mitsuba roughconductor | symbolic (default) | {t:.2f} | – | – | – | – | – |")
    sm.enable_evaluated_mode()
    rows = [("Mitsuba roughconductor", builtin, None),
            ("Mitsuba diffuse", {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.7, 0.7, 0.7]}}, None)]
    with tempfile.TemporaryDirectory() as d:
        p = pathlib.Path(d) / "conductor.toml"
        p.write_text(ONE_INTERFACE)
        rows += [
            ("strata one-interface conductor", {"type": "strata", "filename": str(p)}, sm),
            ("strata coated_copper", {"type": "strata", "filename": str(ROOT / "examples/materials/coated_copper.toml")}, sm),
            ("strata scattering_slab", {"type": "strata", "filename": str(ROOT / "examples/materials/scattering_slab.toml")}, sm),
        ]
        for name, bsdf, stats in rows:
            t, inside, module, calls, queries = timed_render(scene(bsdf), args.repeat, stats)
            if stats:
                print(f"| {name} | evaluated | {t:.2f} | {inside:.2f} | {module:.2f} | {100 * module / t:.0f} % | "
                      f"{calls} | {queries} |")
            else:
                print(f"| {name} | evaluated | {t:.2f} | – | – | – | – | – |")

    print(f"\n## Per-query cost through Python ({args.queries} queries, coated_copper, 1 walk per eval)\n")
    b = strata_bsdf.Bsdf.from_path(ROOT / "examples/materials/coated_copper.toml", samples=1)
    rng = np.random.default_rng(0)

    def dirs(n):
        v = rng.normal(size=(n, 3)).astype(np.float32)
        v[:, 2] = np.abs(v[:, 2]) + 0.1
        return np.ascontiguousarray(v / np.linalg.norm(v, axis=1, keepdims=True), dtype=np.float32)

    n = args.queries
    wi, wo = dirs(n), dirs(n)
    keys = np.arange(n, dtype=np.uint64)
    wi_soa = tuple(np.ascontiguousarray(wi[:, i]) for i in range(3))
    wo_soa = tuple(np.ascontiguousarray(wo[:, i]) for i in range(3))
    singles = max(1, n // 10)
    print("| call | one batch of N (µs/query) | N calls of 1 (µs/query) | ratio |")
    print("|---|---|---|---|")
    for name, batch, single in [
        ("eval", lambda: b.eval(wi, wo, keys), lambda i: b.eval(wi[i : i + 1], wo[i : i + 1], keys[i : i + 1])),
        ("eval (SoA)", lambda: b.eval(wi_soa, wo_soa, keys), None),
        ("sample", lambda: b.sample(wi, keys), lambda i: b.sample(wi[i : i + 1], keys[i : i + 1])),
        ("pdf", lambda: b.pdf(wi, wo), lambda i: b.pdf(wi[i : i + 1], wo[i : i + 1])),
    ]:
        batch()
        t = time.perf_counter()
        for _ in range(3):
            batch()
        tb = (time.perf_counter() - t) / 3 / n * 1e6
        if single is None:
            print(f"| {name} | {tb:.3f} | – | – |")
            continue
        t = time.perf_counter()
        for i in range(singles):
            single(i)
        ts = (time.perf_counter() - t) / singles * 1e6
        print(f"| {name} | {tb:.3f} | {ts:.2f} | {ts / tb:.0f}× |")


if __name__ == "__main__":
    main()
