"""Renders strata's example materials in Mitsuba 3 into docs/gallery/.

    python examples/mitsuba/gallery.py [--spp 64] [--size 256] [--variant llvm_ad_rgb]

Each material of examples/materials/ listed below on a sphere (a checkered
ground, a sky-gradient environment and a sun), one PNG each, and one image
of a strata one-interface stack (rough conductor, GGX alpha 0.3) beside
Mitsuba's own roughconductor with the same parameters. Prints the time of
each render.
"""

import argparse
import pathlib
import sys
import tempfile
import time

import mitsuba as mi
import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(pathlib.Path(__file__).parent))

MATERIALS = ["coated_copper", "clear_coat_lambertian", "varnished_wood", "scattering_slab", "validation1"]
ETA, K = [0.2, 0.92, 1.1], [3.9, 2.45, 2.2]
ONE_INTERFACE = (
    '[[layers]]\ninterface = { kind = "conductor", eta = [0.2, 0.92, 1.1], k = [3.9, 2.45, 2.2], '
    'roughness = 0.3, shadowing = "separable" }\n'
)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--variant", default="llvm_ad_rgb")
    ap.add_argument("--out", default=str(ROOT / "docs" / "gallery"))
    ap.add_argument("--only", nargs="*", help="render only these materials")
    args = ap.parse_args()

    mi.set_variant(args.variant)
    import strata_bsdf.mitsuba as sm
    from common import scene_dict

    if not args.variant.startswith("scalar"):
        sm.enable_evaluated_mode()
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    def render(bsdf, name, seed=0):
        scene = mi.load_dict(scene_dict(mi, bsdf, args.size, args.size, args.spp))
        t = time.perf_counter()
        img = mi.render(scene, seed=seed)
        img = np.array(img)
        dt = time.perf_counter() - t
        assert np.isfinite(img).all(), name
        print(f"{name}: {dt:.1f} s", flush=True)
        return img

    for m in args.only if args.only else MATERIALS:
        path = ROOT / "examples" / "materials" / f"{m}.toml"
        img = render({"type": "strata", "filename": str(path), "samples": 1}, m)
        mi.util.write_bitmap(str(out / f"{m}.png"), img)

    if not args.only:
        with tempfile.TemporaryDirectory() as d:
            p = pathlib.Path(d) / "conductor.toml"
            p.write_text(ONE_INTERFACE)
            a = render({"type": "strata", "filename": str(p)}, "strata one-interface conductor")
        b = render(
            {"type": "roughconductor", "distribution": "ggx", "alpha": 0.3,
             "eta": {"type": "rgb", "value": ETA}, "k": {"type": "rgb", "value": K}},
            "mitsuba roughconductor",
        )
        gap = np.ones((a.shape[0], 4, 3), np.float32)
        mi.util.write_bitmap(str(out / "strata_vs_mitsuba_roughconductor.png"), np.concatenate([a, gap, b], axis=1))
        print(f"image means: strata {a.mean():.5f}, mitsuba {b.mean():.5f} ({100 * (a.mean() / b.mean() - 1):+.2f} %)")


if __name__ == "__main__":
    main()
