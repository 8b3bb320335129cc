"""Renders strata's example materials in Mitsuba 3 into docs/gallery/.

    python examples/mitsuba/gallery.py [--spp 64] [--size 256] [--variant llvm_ad_rgb]
    python examples/mitsuba/gallery.py --textured [--spp 64] [--size 256]

Each material of examples/materials/ listed below on a sphere (a checkered
ground, a sky-gradient environment and a sun), one PNG each, and one image
of a strata one-interface stack (rough conductor, GGX alpha 0.3) beside
Mitsuba's own roughconductor with the same parameters. Prints the time of
each render.

With --textured, instead: three spatially varying materials, their textures
made here with numpy (nothing read from disk) and handed to the plugin as
``param:`` properties (per-query parameters): a clear coat with an amber
absorber whose thickness follows a bitmap of bands (textured_thickness.png),
and a rough coat over silver whose absorber's sigma_t is an RGB bitmap of
tinted cells (textured_sigma_t.png); and a clear coat over rough copper whose
coat alone follows a normal map of hammered dimples (textured_normal.png; the
copper below keeps the slab's normal). The bitmaps take a few distinct values
(nearest filtering), so a wavefront has a few distinct materials.
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
from common import normal_map  # noqa: E402

MATERIALS = ["coated_copper", "clear_coat_lambertian", "varnished_wood", "scattering_slab", "validation1",
             "fibers_under_coat", "jade"]
ETA, K = [0.2, 0.92, 1.1], [3.9, 2.45, 2.2]
ONE_INTERFACE = (
    '[[layers]]\ninterface = { kind = "conductor", eta = [0.2, 0.92, 1.1], k = [3.9, 2.45, 2.2], '
    'roughness = 0.3, shadowing = "separable" }\n'
)


# A smooth clear coat with an amber absorber over a near-white Lambertian base:
# the thicker the coat, the deeper the amber (optical depth thickness x sigma_t).
AMBER_COAT = """description = "Clear coat with an amber absorber, thickness from a texture"
[[layers]]
interface = { kind = "dielectric", ior = 1.5 }
medium = { thickness = 0.5, sigma_t = [0.15, 0.6, 1.8], albedo = 0.0 }
[[layers]]
interface = { kind = "diffuse", albedo = 0.85 }
"""

# A clear coat over rough copper, the coat alone normal-mapped (hammered).
HAMMERED_COAT = """description = "Clear coat over rough copper, the coat's normal from a normal map"
[[layers]]
interface = { kind = "dielectric", ior = 1.5 }
medium = { thickness = 0.3, sigma_t = [0.1, 0.25, 0.5], albedo = 0.0 }
[[layers]]
interface = { kind = "conductor", preset = "Cu", roughness = 0.25 }
"""

# A rough coat over silver, its absorber's colour from a texture.
TINTED_SILVER = """description = "Rough coat over silver, the absorber's sigma_t from an RGB texture"
[[layers]]
interface = { kind = "dielectric", ior = 1.5, roughness = 0.08 }
medium = { thickness = 1.0, sigma_t = [0.5, 0.5, 0.5], albedo = 0.0 }
[[layers]]
interface = { kind = "conductor", preset = "Ag", roughness = 0.15 }
"""


def thickness_bands(width=512, height=256, levels=8):
    """Thickness in (u, v) (Mitsuba's sphere: u around the axis, v from pole
    to pole): wavy bands in 8 steps from 0.05 to 2.0 (nearest filtering keeps
    the steps, so a wavefront holds 8 distinct materials)."""
    u = (np.arange(width) + 0.5) / width
    v = (np.arange(height) + 0.5) / height
    uu, vv = np.meshgrid(u, v)
    t = 0.5 + 0.5 * np.sin(2 * np.pi * (6 * vv + 0.6 * np.sin(2 * np.pi * 3 * uu)))
    q = np.minimum(np.floor(t * levels), levels - 1) / (levels - 1)
    return (0.05 + 1.95 * q).astype(np.float32)[:, :, None]


PALETTE = np.array(
    [[0.05, 0.6, 1.6], [1.4, 0.35, 0.1], [0.1, 1.2, 0.9], [1.0, 1.2, 0.08], [0.9, 0.1, 0.9], [0.02, 0.02, 0.02]],
    np.float32,
)


def sigma_cells(width=256, height=128, seed=1):
    """An RGB sigma_t in (u, v): Voronoi cells (24 random sites, distances
    wrapped in u), each one colour of a palette of absorbers (clear,
    blue, red, green-blue, yellow, magenta tints)."""
    rng = np.random.default_rng(seed)
    sites = rng.random((24, 2))
    colours = rng.integers(0, len(PALETTE), size=24)
    u = (np.arange(width) + 0.5) / width
    v = (np.arange(height) + 0.5) / height
    uu, vv = np.meshgrid(u, v)
    du = np.abs(uu[..., None] - sites[:, 0])
    du = np.minimum(du, 1 - du) * 2  # u spans twice v's length on the sphere
    d = du**2 + (vv[..., None] - sites[:, 1]) ** 2
    return PALETTE[colours[d.argmin(axis=-1)]]


def hammered_normals(width=256, height=128, seed=2, levels=4):
    """A normal map in (u, v) (RGB c = (n + 1) / 2, as Mitsuba's normalmap
    reads it): round dimples around 40 random sites (distances wrapped in
    u), each a spherical cap tilting the normal up to 20 degrees, the tilt
    quantized to a few values per axis so that a wavefront holds a few
    distinct materials."""
    rng = np.random.default_rng(seed)
    sites = rng.random((40, 2))
    u = (np.arange(width) + 0.5) / width
    v = (np.arange(height) + 0.5) / height
    uu, vv = np.meshgrid(u, v)
    du = uu[..., None] - sites[:, 0]
    du = (du + 0.5) % 1.0 - 0.5
    dv = vv[..., None] - sites[:, 1]
    d2 = (2 * du) ** 2 + dv**2
    k = d2.argmin(axis=-1)
    pick = lambda a: np.take_along_axis(a, k[..., None], axis=-1)[..., 0]  # noqa: E731
    x, y, r = 2 * pick(du), pick(dv), np.sqrt(pick(d2))
    radius = 0.09
    s = np.clip(r / radius, 0.0, 1.0) * np.tan(np.radians(20.0))
    with np.errstate(invalid="ignore", divide="ignore"):
        tx = np.where(r > 0, s * x / r, 0.0)
        ty = np.where(r > 0, s * y / r, 0.0)
    return normal_map(tx, ty, levels)


def bitmap(mi, data):
    return {"type": "bitmap", "bitmap": mi.Bitmap(data), "raw": True, "filter_type": "nearest"}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--variant", default="llvm_ad_rgb")
    ap.add_argument("--out", default=str(ROOT / "docs" / "gallery"))
    ap.add_argument("--only", nargs="*", help="render only these materials")
    ap.add_argument("--textured", action="store_true", help="render the three textured materials instead")
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

    if args.textured:
        with tempfile.TemporaryDirectory() as d:
            coat, silver = pathlib.Path(d) / "amber_coat.toml", pathlib.Path(d) / "tinted_silver.toml"
            coat.write_text(AMBER_COAT)
            silver.write_text(TINTED_SILVER)
            img = render({"type": "strata", "filename": str(coat),
                          "param:layers[0]:medium:thickness": bitmap(mi, thickness_bands())},
                         "textured_thickness")
            mi.util.write_bitmap(str(out / "textured_thickness.png"), img)
            img = render({"type": "strata", "filename": str(silver),
                          "param:layers[0]:medium:sigma_t": bitmap(mi, sigma_cells())},
                         "textured_sigma_t")
            mi.util.write_bitmap(str(out / "textured_sigma_t.png"), img)
            hammered = pathlib.Path(d) / "hammered_coat.toml"
            hammered.write_text(HAMMERED_COAT)
            img = render({"type": "strata", "filename": str(hammered),
                          "param:layers[0]:interface:normal": bitmap(mi, hammered_normals())},
                         "textured_normal")
            mi.util.write_bitmap(str(out / "textured_normal.png"), img)
        return

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
