"""Renders a dispersive coat in Mitsuba 3's spectral variant into docs/gallery/dispersion.png.

    python examples/mitsuba/dispersion.py [--size 512] [--spp 128] [--out docs/gallery]

examples/materials/dispersive_prism.toml (a clear coat of Abbe number 6 over
smooth silver tilted under it: a prism) on a sphere, lit by a slit (a thin
bright rectangle) in a dim room, in ``llvm_ad_spectral``: the plugin answers
at the four wavelengths Mitsuba samples per path, and the coat's IOR is read
at each (bindings/python/README.md, *Spectral variants*). Beside it, the same
material with its IOR fixed at nd = 1.6 through a ``param:`` property: one
highlight, where the dispersive coat spreads it into a spectrum. Prints the
time of each render and the horizontal offset (in pixels) of the
highlight's blue part from its red part, and writes the two renders side by
side. ``--tiny`` renders 32x32 at 4 spp (for the tests).
"""

import argparse
import json
import pathlib
import time

import mitsuba as mi
import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[2]
MATERIAL = ROOT / "examples" / "materials" / "dispersive_prism.toml"


def scene(bsdf, size, spp):
    """The sphere (its pole up, so that the tilt of the silver, along the
    surface's first tangent, runs east-west) under a slit light above and
    behind the camera, in a dim uniform room."""
    return mi.load_dict({
        "type": "scene",
        "integrator": {"type": "path", "max_depth": 6},
        "sensor": {
            "type": "perspective",
            "fov": 30,
            "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 4.5], target=[0, 0, 0], up=[0, 1, 0]),
            "film": {"type": "hdrfilm", "width": size, "height": size, "rfilter": {"type": "gaussian"}},
            "sampler": {"type": "independent", "sample_count": spp},
        },
        "room": {"type": "constant", "radiance": {"type": "rgb", "value": [0.05, 0.05, 0.06]}},
        "slit": {
            "type": "rectangle",
            "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0.6, 5.5], target=[0, 0, 0], up=[0, 1, 0])
            @ mi.ScalarTransform4f().scale([0.03, 0.5, 1]),
            "emitter": {"type": "area", "radiance": {"type": "d65", "scale": 100.0}},
        },
        "sphere": {"type": "sphere", "to_world": mi.ScalarTransform4f().rotate([1, 0, 0], -90), "bsdf": bsdf},
    })


def split(img):
    """The highlight's blue centroid minus its red centroid, in pixels along
    x, over the brightest pixels of the right half (the highlight through
    the coat; the coat's own reflection of the slit is at the centre)."""
    img = img[:, img.shape[1] // 2 + 2 :]
    lum = img.sum(axis=2)
    bright = lum > np.quantile(lum, 0.99)
    x = np.arange(img.shape[1])[None, :].repeat(img.shape[0], axis=0)
    red, blue = img[..., 0] * bright, img[..., 2] * bright
    return float((blue * x).sum() / blue.sum() - (red * x).sum() / red.sum())


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--spp", type=int, default=128)
    ap.add_argument("--out", default=str(ROOT / "docs" / "gallery"))
    ap.add_argument("--tiny", action="store_true", help="32x32 at 4 spp")
    args = ap.parse_args()
    size, spp = (32, 4) if args.tiny else (args.size, args.spp)

    mi.set_variant("llvm_ad_spectral")
    import strata_bsdf.mitsuba as sm

    sm.enable_evaluated_mode()
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    strata = {"type": "strata", "filename": str(MATERIAL), "config": "threads=1"}
    imgs, report = [], {"size": size, "spp": spp, "variant": mi.variant()}
    for name, bsdf in [("dispersive", strata), ("ior fixed at nd", dict(strata, **{"param:layers[0]:interface:ior": 1.6}))]:
        t = time.perf_counter()
        img = np.array(mi.render(scene(bsdf, size, spp), seed=1))
        dt = time.perf_counter() - t
        assert np.isfinite(img).all(), name
        imgs.append(img)
        report[name] = {"seconds": round(dt, 1), "blue_minus_red_px": round(split(img), 2)}
        print(f"{name}: {dt:.1f} s, blue - red {split(img):+.1f} px", flush=True)
    mi.util.write_bitmap(str(out / "dispersion.png"), np.concatenate(imgs, axis=1))
    (out / "dispersion.json").write_text(json.dumps(report, indent=1) + "\n")


if __name__ == "__main__":
    main()
