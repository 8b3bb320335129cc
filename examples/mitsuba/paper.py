"""The paper's results, rendered (issue 43): white furnace tests, the
performance table, the paper's subjects and an equal-time comparison, in
Mitsuba 3 through the strata plugin, on ONE thread.

    python examples/mitsuba/paper.py --all             # everything, in this order
    python examples/mitsuba/paper.py --furnace         # white furnace tests
    python examples/mitsuba/paper.py --table           # render times: strata uni / bidir / diffuse
    python examples/mitsuba/paper.py --subjects [NAME ...]  # the figures (default: all)
    python examples/mitsuba/paper.py --compare         # equal time: strata vs explicit geometry

Options: --out (default docs/gallery/paper), --spp-scale (multiplies every
figure's samples per pixel; 1 by default), --tiny (16x16 at 4 spp, to check
that the scripts run).

Every material is a file under examples/materials/paper/; the textures and
the environment are made here with numpy (nothing is read or downloaded).
Renders use llvm_ad_rgb in evaluated mode (the mode the Python plugin needs),
Dr.Jit on one thread, and strata's batches on the calling thread
(``threads=1``; RAYON_NUM_THREADS=1 too). Prints the time of each render.
"""

import argparse
import gc
import json
import math
import os
import pathlib
import statistics
import sys
import time

os.environ.setdefault("RAYON_NUM_THREADS", "1")

import drjit as dr  # noqa: E402
import mitsuba as mi  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, str(pathlib.Path(__file__).parent))
import common  # noqa: E402  (the gallery's scene helpers)

ROOT = pathlib.Path(__file__).resolve().parents[2]
MAT = ROOT / "examples" / "materials" / "paper"

T = None  # mi.ScalarTransform4f, once a variant is set (setup())
TINY = False
LOG = []  # (name, seconds, note) of every render


def setup():
    global T
    mi.set_variant("llvm_ad_rgb")
    mi.set_log_level(mi.LogLevel.Warn)
    dr.set_thread_count(1)
    import strata_bsdf.mitsuba as sm

    sm.enable_evaluated_mode()
    T = mi.ScalarTransform4f


def strata(name, **params):
    """A strata BSDF dict for examples/materials/paper/<name>.toml, with
    ``param:`` textures given as path=dict (``layers[0].medium.thickness``)."""
    d = {"type": "strata", "filename": str(MAT / f"{name}.toml"), "samples": 1, "seed": 0}
    for path, tex in params.items():
        d["param:" + path.replace(".", ":")] = tex
    return d


def configure(scene_d, config):
    """A copy of a scene dict whose strata BSDFs take the settings `config`
    (``estimator=bidir``) and ``threads=1``, through the plugin's ``config``
    property."""
    if isinstance(scene_d, dict):
        d = {k: configure(v, config) for k, v in scene_d.items()}
        if d.get("type") == "strata":
            d["config"] = f"threads=1 {config}"
        return d
    if isinstance(scene_d, list):
        return [configure(v, config) for v in scene_d]
    return scene_d


MAX_LANES = 4_200_000  # samples per pass: a JIT render holds all of its samples at once


def render(scene_d, name, config="", seed=0, quiet=False):
    """Loads and renders a scene dict; returns (image as numpy, seconds).
    Renders in passes of at most MAX_LANES samples (in evaluated mode every
    sample's state is in memory at once: 84 million samples ran out of
    24 GB), each with its own seed, and averages them."""
    scene = mi.load_dict(configure(scene_d, config))
    film = scene_d["sensor"]["film"]
    spp = scene_d["sensor"]["sampler"]["sample_count"]
    per = max(1, min(spp, MAX_LANES // (film["width"] * film["height"])))
    while spp % per:
        per -= 1
    t = time.perf_counter()
    acc = None
    for i in range(spp // per):
        img = np.array(mi.render(scene, seed=seed * 1000 + i, spp=per))
        acc = img if acc is None else acc + img
    img = acc / (spp // per)
    dt = time.perf_counter() - t
    assert np.isfinite(img).all(), name
    if not quiet:
        print(f"  render {name}: {dt:.1f} s" + (f" ({spp // per} passes of {per} spp)" if per < spp else ""),
              flush=True)
    LOG.append((name, dt))
    return img, dt


def save(img, out, name):
    path = out / f"{name}.png"
    mi.util.write_bitmap(str(path), img[:, :, :3], write_async=False)
    kb = path.stat().st_size / 1024
    print(f"  wrote {path} ({img.shape[1]}x{img.shape[0]}, {kb:.0f} KB)", flush=True)
    assert kb <= 1536, f"{path} is larger than 1.5 MB"
    return path


# --------------------------------------------------------------------------
# Scenes


def sky(width=128, height=64, ground=(0.12, 0.1, 0.08)):
    """The gallery's equirectangular sky (common.py) at this script's size."""
    return common.sky(mi, width, height, ground)


def checker_ground(y=-1.0, scale=8.0, tiles=8.0):
    return {
        "type": "rectangle",
        "to_world": T().translate([0, y, 0]).rotate([1, 0, 0], -90).scale(scale),
        "bsdf": {"type": "diffuse", "reflectance": {
            "type": "checkerboard",
            "color0": {"type": "rgb", "value": [0.35, 0.35, 0.35]},
            "color1": {"type": "rgb", "value": [0.6, 0.6, 0.6]},
            "to_uv": T().scale([tiles, tiles, 1])}},
    }


def base_scene(width, height, spp, origin=(0, 1.2, 4.6), target=(0, 0.05, 0), fov=32, depth=8,
               sun=(-0.6, -1.0, -0.5), sun_power=(3.0, 2.9, 2.7), env_scale=0.8, rfilter="gaussian"):
    d = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": depth},
        "sensor": {
            "type": "perspective", "fov": fov,
            "to_world": T().look_at(origin=list(origin), target=list(target), up=[0, 1, 0]),
            "film": {"type": "hdrfilm", "width": width, "height": height, "rfilter": {"type": rfilter}},
            "sampler": {"type": "independent", "sample_count": spp},
        },
        "env": {"type": "envmap", "bitmap": sky(), "scale": env_scale},
    }
    if sun is not None:
        d["sun"] = {"type": "directional", "direction": list(sun), "irradiance": {"type": "rgb", "value": list(sun_power)}}
    return d


def sphere_scene(bsdf, size, spp, depth=8):
    d = base_scene(size, size, spp, depth=depth)
    d["sphere"] = {"type": "sphere", "radius": 1.0, "bsdf": bsdf}
    d["ground"] = checker_ground()
    return d


def bitmap(data, nearest=True):
    d = {"type": "bitmap", "bitmap": mi.Bitmap(np.ascontiguousarray(data, np.float32)), "raw": True}
    if nearest:
        d["filter_type"] = "nearest"
    return d


# --------------------------------------------------------------------------
# White furnace

FURNACE = [
    ("furnace_smooth_slab", True),
    ("furnace_scattering_slab", True),
    ("furnace_smooth_coat_white", False),
    ("furnace_rough_slab", True),
    ("furnace_rough_coat_scatterer", False),
    ("furnace_rough_conductor_white", False),
]


def furnace_scene(bsdf, size, spp, shape="sphere"):
    """A uniform environment of radiance 1 and one object, seen through an
    orthographic camera (every ray parallel): on the sphere a pixel at
    radius r (in the sphere's units) sees the surface at cos(theta) =
    sqrt(1 - r^2); the tile is tilted 60 degrees, cos(theta) = 0.5 at every
    pixel."""
    d = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": 128, "rr_depth": 64},
        "sensor": {
            "type": "orthographic",
            "to_world": T().look_at(origin=[0, 0, 5], target=[0, 0, 0], up=[0, 1, 0]).scale([1.1, 1.1, 1]),
            "film": {"type": "hdrfilm", "width": size, "height": size, "rfilter": {"type": "box"}},
            "sampler": {"type": "independent", "sample_count": spp},
        },
        "env": {"type": "constant", "radiance": {"type": "rgb", "value": 1.0}},
    }
    if shape == "sphere":
        d["obj"] = {"type": "sphere", "radius": 1.0, "bsdf": bsdf}
    else:
        d["obj"] = {"type": "rectangle", "to_world": T().rotate([1, 0, 0], -60).scale(0.8), "bsdf": bsdf}
    return d


def strata_albedo(name, mus, walks):
    """strata's directional albedo R + T (per RGB channel, averaged) at
    viewing cosines ``mus``, in importance transport (wi = the viewer, as a
    camera path queries it)."""
    import strata_bsdf

    b = strata_bsdf.Bsdf.from_path(MAT / f"{name}.toml", seed=1, transport="importance").configure("threads=1")
    mus = np.asarray(mus, np.float64)
    wi = np.stack([np.sqrt(1 - mus**2), np.zeros_like(mus), mus], axis=1).astype(np.float32)
    R, Tr, R_se, T_se = b.albedo(wi, walks)
    a = (np.asarray(R) + np.asarray(Tr)).mean(axis=1)
    se = np.sqrt(np.asarray(R_se) ** 2 + np.asarray(T_se) ** 2).mean(axis=1)
    return a, se, np.asarray(R).mean(axis=1), np.asarray(Tr).mean(axis=1)


def run_furnace(args, out):
    size, spp, walks = (16, 4, 64) if TINY else (256, 128, 16384)
    print(f"\n== White furnace: {size}x{size}, {spp} spp, orthographic, constant environment of radiance 1, "
          f"path depth 128", flush=True)
    rows = []
    tiles = []
    # Pixel centres in the sphere's units (orthographic, half-width 1.1).
    c = ((np.arange(size) + 0.5) / size * 2 - 1) * 1.1
    r = np.sqrt(c[None, :] ** 2 + c[:, None] ** 2)
    mask = r < 0.97
    mu_px = np.sqrt(np.clip(1 - r**2, 0, 1))
    mus = np.linspace(0.2, 1.0, 33)
    mus = np.concatenate([[0.01, 0.03, 0.06, 0.1, 0.15], mus])
    images = []
    for name, transmits in FURNACE:
        img, dt = render(furnace_scene(strata(name), size, spp), name)
        a, se, R, Tr = strata_albedo(name, mus, walks)
        pred = np.interp(mu_px[mask], mus, a).mean()
        mean = img[..., :3].mean(axis=2)[mask].mean()
        row = {"material": name, "render_s": dt, "sphere_mean": float(mean), "albedo_mean": float(pred),
               "albedo_normal": float(a[-1]), "albedo_min_mu": float(a[0]), "transmits": transmits}
        if transmits:
            timg, tdt = render(furnace_scene(strata(name), size // 2, spp, shape="tile"), name + " (tile)")
            h = size // 2
            # The tile's middle (it spans 0.8 x 0.4 of the half-width 1.1 view).
            m = timg[h // 2 - h // 8: h // 2 + h // 8, h // 2 - h // 4: h // 2 + h // 4, :3].mean()
            a5, se5, R5, T5 = strata_albedo(name, [0.5], 4 * walks)
            row.update(tile_mean=float(m), tile_albedo=float(a5[0]), tile_albedo_se=float(se5[0]),
                       tile_R=float(R5[0]), tile_T=float(T5[0]))
            tiles.append(timg)
        rows.append(row)
        images.append(img)
        save(img, out, name)
        msg = (f"  {name}: sphere mean {mean:.4f}, strata albedo over the same pixels {pred:.4f} "
               f"(R+T at normal incidence {a[-1]:.4f}, at cos 0.01 {a[0]:.4f})")
        if transmits:
            msg += (f"; tile at cos 0.5: mean {row['tile_mean']:.4f}, albedo {row['tile_albedo']:.4f} "
                    f"+- {row['tile_albedo_se']:.4f} (R {row['tile_R']:.4f}, T {row['tile_T']:.4f})")
        print(msg, flush=True)
    (out / "furnace.json").write_text(json.dumps(rows, indent=1))
    return rows


# --------------------------------------------------------------------------
# Textures (numpy)


def wood_rings(width=512, height=256, seed=3):
    """A wood-coloured albedo in (u, v): growth rings (light/dark bands,
    distorted by low-frequency noise), in 6 quantized shades."""
    rng = np.random.default_rng(seed)
    u = (np.arange(width) + 0.5) / width
    v = (np.arange(height) + 0.5) / height
    uu, vv = np.meshgrid(u, v)
    warp = sum(rng.uniform(0.02, 0.06) * np.sin(2 * np.pi * (k * uu + rng.random()) + k * vv) for k in (1, 2, 3))
    t = (18 * (vv + warp)) % 1.0
    t = np.round(t ** 2.5 * 5) / 5
    light, dark = np.array([0.62, 0.38, 0.18]), np.array([0.32, 0.16, 0.07])
    return (light * (1 - t[..., None]) + dark * t[..., None]).astype(np.float32)


def swirl_thickness(width=512, height=256, levels=10, lo=0.05, hi=3.0):
    """Thickness in (u, v): interleaved swirls, quantized to ``levels``."""
    u = (np.arange(width) + 0.5) / width
    v = (np.arange(height) + 0.5) / height
    uu, vv = np.meshgrid(u, v)
    t = 0.5 + 0.5 * np.sin(2 * np.pi * (3 * uu + 4 * vv + 0.35 * np.sin(2 * np.pi * (5 * vv + 2 * uu))))
    q = np.minimum(np.floor(t * levels), levels - 1) / (levels - 1)
    return (lo + (hi - lo) * q).astype(np.float32)[:, :, None]


def scattering_maps(width=512, height=256):
    """sigma_t (RGB) and albedo (RGB) in (u, v): stripes across u of six
    media (spectrally different scattering and absorption), and rings across
    v that scale sigma_t (x0.3, x1, x3)."""
    u = (np.arange(width) + 0.5) / width
    v = (np.arange(height) + 0.5) / height
    uu, vv = np.meshgrid(u, v)
    albedos = np.array([[0.99, 0.7, 0.3], [0.3, 0.8, 0.99], [0.95, 0.95, 0.95],
                        [0.9, 0.3, 0.6], [0.4, 0.95, 0.5], [0.99, 0.9, 0.5]], np.float32)
    sigmas = np.array([[2, 2, 2], [1, 2, 4], [4, 4, 4], [3, 1, 2], [2, 3, 1], [4, 2, 1]], np.float32)
    k = (np.floor(uu * 12) % 6).astype(int)
    scale = np.array([0.3, 1.0, 3.0], np.float32)[(np.floor(vv * 6) % 3).astype(int)]
    return sigmas[k] * scale[..., None], albedos[k]


def logo_and_drop(size=512, levels=5):
    """The logo_drop textures in (u, v) of a unit tile: a logo (a ring with
    a bar through it, the letter-like mark 'theta'), and a water drop (a
    round cap at one side of the logo, its normal map quantized to
    ``levels`` steps per axis). Returns the four parameter maps."""
    u = (np.arange(size) + 0.5) / size
    uu, vv = np.meshgrid(u, u)
    x, y = uu - 0.5, vv - 0.5
    rr = np.sqrt(x**2 + y**2)
    logo = ((rr > 0.22) & (rr < 0.32)) | ((np.abs(y) < 0.045) & (np.abs(x) < 0.22))
    logo |= (np.abs(x - 0.0) < 0.045) & (y > 0.32) & (y < 0.42)  # a stem at the top
    # The drop: a spherical cap of radius 0.13 centred off the logo's centre.
    cx, cy, rad = 0.16, 0.1, 0.13
    dx, dy = x - cx, y - cy
    d = np.sqrt(dx**2 + dy**2)
    drop = d < rad
    slope = np.where(drop, np.clip(d / rad, 0, 1) * math.tan(math.radians(35)), 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        tx = np.where(d > 0, slope * dx / d, 0.0)
        ty = np.where(d > 0, slope * dy / d, 0.0)
    nmap = common.normal_map(tx, ty, levels)
    ior0 = np.where(drop, 1.33, 1.0).astype(np.float32)
    ior1 = np.where(logo, 1.5, ior0).astype(np.float32)
    thick = np.where(logo, 1.0, 0.0).astype(np.float32)
    return ior0[..., None], nmap, ior1[..., None], thick[..., None]


# --------------------------------------------------------------------------
# The subjects

SUBJECTS = ["materials", "top_bottom", "refl_trans", "thickness", "scattering", "microflake", "logo_drop"]
# (width, height, spp): chosen for the time budget of one thread (docs/gallery/paper.md).
SIZES = {
    "materials": (1280, 512, 256),
    "top_bottom": (1024, 512, 64),
    "refl_trans": (512, 512, 256),  # two panels
    "thickness": (512, 512, 256),
    "scattering": (512, 512, 256),
    "microflake": (512, 512, 256),
    "logo_drop": (512, 512, 128),
}


def subject_scene(name, w, h, spp):
    if name == "materials":
        mats = ["metal", "wood", "plastic", "ceramics", "glass"]
        d = base_scene(w, h, spp, origin=(0, 2.2, 11.5), target=(0, 0.0, 0), fov=50, depth=10)
        for i, m in enumerate(mats):
            params = {}
            if m == "wood":
                params["layers[1].interface.albedo"] = bitmap(wood_rings())
            d[f"s{i}"] = {"type": "sphere", "radius": 1.0, "center": [(i - 2) * 2.3, 0, 0], "bsdf": strata(m, **params)}
        d["ground"] = checker_ground(scale=14, tiles=14)
        return d
    if name == "top_bottom":
        # No ground: a sun from below (its light travels upwards) and a pale lower half of the
        # environment light the spheres from below, the sky from above.
        d = base_scene(w, h, spp, origin=(0, 1.0, 7.5), target=(0, 0.0, 0), fov=38, depth=12,
                       sun=(0.35, 0.8, -0.5), sun_power=(3.0, 2.9, 2.7))
        d["env"]["bitmap"] = sky(ground=(0.55, 0.55, 0.5))
        d["top"] = {"type": "sphere", "radius": 1.0, "center": [-1.25, 0, 0], "bsdf": strata("two_faced_slab")}
        d["bottom"] = {"type": "sphere", "radius": 1.0, "center": [1.25, 0, 0], "flip_normals": True,
                       "bsdf": strata("two_faced_slab")}
        return d
    if name.startswith("refl_trans"):
        front = name.endswith("front")
        d = base_scene(w, h, spp, origin=(0, 0.6, 5.0), target=(0, 0.0, 0), fov=40, depth=10,
                       sun=(0.3, -0.5, -1.0) if front else (-0.12, -0.2, 1.0),
                       sun_power=(3.0, 2.9, 2.7) if front else (0.8, 0.77, 0.72), env_scale=0.3)
        d["card"] = {"type": "rectangle", "to_world": T().rotate([0, 1, 0], 20).scale([1.2, 1.2, 1]),
                     "bsdf": strata("translucent_sheet")}
        d["ground"] = checker_ground(y=-1.3)
        return d
    if name == "thickness":
        return sphere_scene(strata("varying_thickness", **{"layers[0].medium.thickness": bitmap(swirl_thickness())}),
                            w, spp)
    if name == "scattering":
        st, al = scattering_maps()
        return sphere_scene(strata("varying_scattering", **{"layers[0].medium.sigma_t": bitmap(st),
                                                             "layers[0].medium.albedo": bitmap(al)}), w, spp)
    if name == "microflake":
        return sphere_scene(strata("microflake_over_diffuse"), w, spp)
    if name == "logo_drop":
        ior0, nmap, ior1, thick = logo_and_drop()
        bsdf = strata("logo_drop", **{"layers[0].interface.ior": bitmap(ior0),
                                      "layers[0].interface.normal": bitmap(nmap),
                                      "layers[1].interface.ior": bitmap(ior1),
                                      "layers[1].medium.thickness": bitmap(thick)})
        d = base_scene(w, h, spp, origin=(0, 3.2, 2.6), target=(0, 0.0, 0.1), fov=40, depth=8,
                       sun=(-0.5, -1.0, -0.9))
        d["tile"] = {"type": "rectangle", "to_world": T().rotate([1, 0, 0], -90).scale(1.2), "bsdf": bsdf}
        return d
    raise ValueError(name)


def run_subjects(args, out, names):
    print("\n== The paper's subjects", flush=True)
    done = {}
    for name in names:
        w, h, spp = SIZES[name]
        spp = max(1, int(round(spp * args.spp_scale)))
        if TINY:
            w, h, spp = 16, 16, 4
        if name == "refl_trans":
            a, ta = render(subject_scene("refl_trans_front", w, h, spp), "refl_trans (sun in front)")
            b, tb = render(subject_scene("refl_trans_back", w, h, spp), "refl_trans (sun behind)")
            gap = np.ones((h, max(1, w // 128), 3), np.float32)
            img, dt = np.concatenate([a[..., :3], gap, b[..., :3]], axis=1), ta + tb
        else:
            img, dt = render(subject_scene(name, w, h, spp), name)
        save(img, out, name)
        done[name] = {"width": w, "height": h, "spp": spp, "render_s": dt}
    p = out / "subjects.json"
    old = json.loads(p.read_text()) if p.exists() else {}
    old.update(done)
    p.write_text(json.dumps(old, indent=1))
    return done


# --------------------------------------------------------------------------
# The performance table

TABLE = [
    ("metal", "Layered metal (rough lacquer, absorber, rough gold)"),
    ("plastic", "Plastic (rough coat, scattering body depth 6, white base)"),
    ("ceramics", "Ceramics (3 interfaces, body depth 12)"),
    ("glass", "Glass (transmissive, rough both sides)"),
    ("two_faced_slab", "Two-faced slab (3 interfaces, transmissive)"),
    ("microflake_over_diffuse", "SGGX fibres over diffuse"),
    ("logo_drop", "Logo and drop (3 interfaces, 4 textures)"),
]


def run_table(args, out):
    size, spp, turns = (16, 4, 1) if TINY else (args.table_size, args.table_spp, args.turns)
    print(f"\n== Performance: {size}x{size}, {spp} spp, path depth 8, the sphere scene; "
          f"{turns} turns of (diffuse, uni, bidir), median", flush=True)
    trivial = {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.5, 0.5, 0.5]}}
    rows = []
    # For reference: the trivial scene in Dr.Jit's default symbolic mode,
    # Mitsuba's usual mode (a Python BSDF cannot run in it).
    with symbolic_mode():
        s = mi.load_dict(sphere_scene(trivial, size, spp))
        np.array(mi.render(s, seed=0))
        sym = []
        for turn in range(turns):
            t = time.perf_counter()
            np.array(mi.render(s, seed=turn + 1))
            sym.append(time.perf_counter() - t)
    print(f"  diffuse in symbolic mode: {statistics.median(sym):.2f} s (" + "/".join(f"{x:.2f}" for x in sym) + ")",
          flush=True)
    rows.append({"material": "diffuse_symbolic", "diffuse_s": statistics.median(sym), "all": sym})
    for name, label in TABLE:
        if name == "logo_drop":
            ior0, nmap, ior1, thick = logo_and_drop(256)
            bsdf = strata(name, **{"layers[0].interface.ior": bitmap(ior0), "layers[0].interface.normal": bitmap(nmap),
                                   "layers[1].interface.ior": bitmap(ior1), "layers[1].medium.thickness": bitmap(thick)})
        else:
            bsdf = strata(name)
        scenes = {"diffuse": (sphere_scene(trivial, size, spp), ""),
                  "uni": (sphere_scene(bsdf, size, spp), "estimator=uni"),
                  "bidir": (sphere_scene(bsdf, size, spp), "estimator=bidir")}
        loaded = {}
        for k, (d, cfg) in scenes.items():
            s = mi.load_dict(configure(d, cfg))
            np.array(mi.render(s, seed=0))  # warm-up (kernel compilation)
            loaded[k] = s
        times = {k: [] for k in scenes}
        for turn in range(turns):
            for k, s in loaded.items():
                t = time.perf_counter()
                np.array(mi.render(s, seed=turn + 1))
                times[k].append(time.perf_counter() - t)
        med = {k: statistics.median(v) for k, v in times.items()}
        row = {"material": name, "label": label, **{f"{k}_s": med[k] for k in med},
               "all": times, "uni_ratio": med["uni"] / med["diffuse"], "bidir_ratio": med["bidir"] / med["diffuse"]}
        rows.append(row)
        print(f"  {name}: diffuse {med['diffuse']:.2f} s, uni {med['uni']:.2f} s ({row['uni_ratio']:.1f}x), "
              f"bidir {med['bidir']:.2f} s ({row['bidir_ratio']:.1f}x)   turns: "
              + ", ".join(f"{k} " + "/".join(f"{x:.2f}" for x in v) for k, v in times.items()), flush=True)
        LOG.append((f"table {name}", sum(sum(v) for v in times.values())))
    (out / "table.json").write_text(json.dumps(rows, indent=1))
    return rows


# --------------------------------------------------------------------------
# Equal-time comparison


SHELL = 0.02  # the brute-force shell's thickness (the sphere's radius is 1)


def compare_lights(d):
    """The comparison's lights: the sky, and a small round sun (a sphere
    emitter subtending about 5 degrees; not a delta light, so that paths
    through the brute-force shell's smooth coat can reach it)."""
    d["sun"] = {"type": "sphere", "radius": 0.5, "center": [-5.5, 9.0, 5.0],
                "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [420.0, 400.0, 370.0]}}}
    return d


def compare_scene(kind, size, spp, bsdf=None):
    """The sphere scene with the comparison's material: ``strata``, ``brute``
    (explicit geometry in volpath) or ``approx`` (a given Mitsuba BSDF)."""
    d = base_scene(size, size, spp, depth=32 if kind == "brute" else 8, sun=None, env_scale=1.0)
    d["ground"] = checker_ground()
    compare_lights(d)
    if kind == "strata":
        d["sphere"] = {"type": "sphere", "radius": 1.0, "bsdf": strata("compare_coat")}
    elif kind == "approx":
        d["sphere"] = {"type": "sphere", "radius": 1.0, "bsdf": bsdf}
    else:
        d["integrator"] = {"type": "volpath", "max_depth": 32}
        d["medium"] = {"type": "homogeneous", "sigma_t": 1.0 / SHELL,
                       "albedo": {"type": "rgb", "value": [0.9, 0.6, 0.3]}, "phase": {"type": "hg", "g": 0.3}}
        d["coat"] = {"type": "sphere", "radius": 1.0, "interior": {"type": "ref", "id": "medium"},
                     "bsdf": {"type": "dielectric", "int_ior": 1.5, "ext_ior": 1.0}}
        d["base"] = {"type": "sphere", "radius": 1.0 - SHELL, "exterior": {"type": "ref", "id": "medium"},
                     "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": 0.5}}}
    return d


class symbolic_mode:
    """Dr.Jit's default (symbolic) mode for a render without strata, which
    does not need the evaluated mode (and runs 3-4x faster in its own)."""

    def __enter__(self):
        # A symbolic call traces every live instance of the BSDF domain: let
        # no strata BSDF of an earlier scene (kept by a reference cycle) be one.
        gc.collect()
        dr.set_flag(dr.JitFlag.SymbolicLoops, True)
        dr.set_flag(dr.JitFlag.SymbolicCalls, True)

    def __exit__(self, *a):
        dr.set_flag(dr.JitFlag.SymbolicLoops, False)
        dr.set_flag(dr.JitFlag.SymbolicCalls, False)


def rel_error(img, ref, mask=None):
    """Relative error per pixel |img - ref| / (ref + 0.01), channel mean;
    and the relative RMSE and mean relative error over the pixels of
    ``mask`` (all pixels without one)."""
    e = np.abs(img[..., :3] - ref[..., :3]) / (ref[..., :3] + 0.01)
    r2 = (img[..., :3] - ref[..., :3]) ** 2 / (ref[..., :3] ** 2 + 1e-4)
    m = np.ones(img.shape[:2], bool) if mask is None else mask
    return e.mean(axis=2), float(np.sqrt(r2[m].mean())), float(e[m].mean())


def blocks(img, k=8):
    """The image averaged over k x k blocks (noise down, the model's
    differences kept)."""
    h, w = img.shape[0] // k * k, img.shape[1] // k * k
    return img[:h, :w, :3].reshape(h // k, k, w // k, k, 3).mean(axis=(1, 3))


def heat(e, top=1.0):
    """A false colour: 0 black, then red, yellow, white at ``top``."""
    x = np.clip(e / top, 0, 1)[..., None] * 3
    return np.concatenate([np.clip(x, 0, 1), np.clip(x - 1, 0, 1), np.clip(x - 2, 0, 1)], axis=2).astype(np.float32)


def body_albedo():
    """The hemispherical (cosine-weighted) albedo of compare_body, per RGB
    channel: the diffuse reflectance the approximations are given."""
    import strata_bsdf

    b = strata_bsdf.Bsdf.from_path(MAT / "compare_body.toml", seed=2).configure("threads=1")
    n = 64
    mu = np.sqrt((np.arange(n) + 0.5) / n)  # cosine-weighted: mu^2 uniform
    wi = np.stack([np.sqrt(1 - mu**2), np.zeros(n), mu], axis=1).astype(np.float32)
    R, Tr, _, _ = b.albedo(wi, 64 if TINY else 8192)
    return np.asarray(R).mean(axis=0)


def run_compare(args, out):
    size = 16 if TINY else args.compare_size
    spp = 4 if TINY else args.compare_spp
    ref_spp = 8 if TINY else args.ref_spp
    print(f"\n== Equal time: {size}x{size}; strata at {spp} spp against explicit geometry in volpath "
          f"(Dr.Jit's symbolic mode) at the same time; references at {ref_spp} spp (strata) and "
          f"{args.brute_ref_factor}x that time for brute force", flush=True)
    a, ta = render(compare_scene("strata", size, spp), f"compare strata {spp} spp")
    # Brute force: a pilot to find its time per sample, then the spp of equal time.
    with symbolic_mode():
        pilot = max(4, spp // 4)
        scene = mi.load_dict(compare_scene("brute", size, pilot))
        np.array(mi.render(scene, seed=0))  # compiles
        t = time.perf_counter()
        np.array(mi.render(scene, seed=1))
        per = (time.perf_counter() - t) / pilot
        bspp = max(1, int(ta / per))
        b, tb = render(compare_scene("brute", size, bspp), f"compare brute force {bspp} spp")
    ra, tra = render(compare_scene("strata", size, ref_spp), f"compare strata reference {ref_spp} spp", seed=7)
    with symbolic_mode():
        rbspp = max(1, int(args.brute_ref_factor * tra / per))
        rb, trb = render(compare_scene("brute", size, rbspp), f"compare brute-force reference {rbspp} spp", seed=7)
    # Each method's error against its own reference (their convergence), over
    # the sphere's pixels (the ground is the same in both), and the two
    # references' difference (the thin-slab model against geometry), also on
    # 8x8 blocks, which average the references' remaining noise away.
    sph = sphere_mask(size)
    ea, rmse_a, mre_a = rel_error(a, ra, sph)
    eb, rmse_b, mre_b = rel_error(b, rb, sph)
    eab, rmse_ab, mre_ab = rel_error(rb, ra, sph)
    bsph = blocks(np.repeat(sph[..., None], 3, axis=2).astype(np.float32))[..., 0] > 0.999
    _, rmse_ab8, mre_ab8 = rel_error(blocks(rb), blocks(ra), bsph)
    mean_a, mean_b = ra[..., :3][sph].mean(axis=0), rb[..., :3][sph].mean(axis=0)
    res = {"size": size, "strata_spp": spp, "strata_s": ta, "brute_spp": bspp, "brute_s": tb,
           "strata_ref_spp": ref_spp, "strata_ref_s": tra, "brute_ref_spp": rbspp, "brute_ref_s": trb,
           "strata_rel_rmse": rmse_a, "strata_mean_rel_err": mre_a,
           "brute_rel_rmse": rmse_b, "brute_mean_rel_err": mre_b,
           "refs_rel_rmse": rmse_ab, "refs_mean_rel_err": mre_ab,
           "refs_rel_rmse_8x8": rmse_ab8, "refs_mean_rel_err_8x8": mre_ab8,
           "sphere_mean_strata_ref": [float(x) for x in mean_a], "sphere_mean_brute_ref": [float(x) for x in mean_b]}
    print(f"  over the sphere's pixels: strata {spp} spp {ta:.1f} s: relative RMSE {rmse_a:.4f}, mean relative error "
          f"{mre_a:.4f} (against strata's reference)", flush=True)
    print(f"  brute force {bspp} spp {tb:.1f} s: relative RMSE {rmse_b:.4f}, mean relative error {mre_b:.4f} "
          f"(against brute force's reference)", flush=True)
    print(f"  the references' difference: relative RMSE {rmse_ab:.4f}, mean relative error {mre_ab:.4f}; on 8x8 "
          f"blocks {rmse_ab8:.4f} and {mre_ab8:.4f}; sphere means strata "
          + " ".join(f"{x:.4f}" for x in mean_a) + ", brute force " + " ".join(f"{x:.4f}" for x in mean_b), flush=True)
    gap = np.ones((size, max(1, size // 64), 3), np.float32)
    top = np.concatenate([a[..., :3], gap, b[..., :3], gap, ra[..., :3], gap, rb[..., :3]], axis=1)
    bot = np.concatenate([heat(ea), gap, heat(eb), gap, heat(eab), gap, np.zeros_like(a[..., :3])], axis=1)
    save(np.concatenate([top, np.ones((gap.shape[1], top.shape[1], 3), np.float32), bot], axis=0), out, "equal_time")

    # Mitsuba's own approximations, against strata's reference.
    alb = body_albedo()
    print(f"  compare_body's hemispherical albedo (the approximations' diffuse reflectance): "
          f"{alb[0]:.4f} {alb[1]:.4f} {alb[2]:.4f}", flush=True)
    rgb = {"type": "rgb", "value": [float(x) for x in alb]}
    approx = {
        "plastic": {"type": "plastic", "int_ior": 1.5, "diffuse_reflectance": rgb},
        "roughplastic": {"type": "roughplastic", "int_ior": 1.5, "alpha": 0.05, "distribution": "ggx",
                         "diffuse_reflectance": rgb},
        "principled": {"type": "principled", "base_color": rgb, "roughness": 1.0, "metallic": 0.0,
                       "specular": 0.0, "clearcoat": 1.0, "clearcoat_gloss": 1.0},
    }
    imgs, errs = [], []
    res["approx"] = {}
    for k, bs in approx.items():
        with symbolic_mode():
            img, dt = render(compare_scene("approx", size, ref_spp, bs), f"compare {k} {ref_spp} spp", seed=7)
        e, rmse, mre = rel_error(img, ra, sph)
        diff = (img[..., :3] - ra[..., :3])[sph].mean(axis=0)
        rel = diff / ra[..., :3][sph].mean(axis=0)
        res["approx"][k] = {"rel_rmse": rmse, "mean_rel_err": mre, "sphere_mean_diff_rel": [float(x) for x in rel],
                            "render_s": dt}
        print(f"  {k}: over the sphere, relative RMSE {rmse:.4f}, mean relative error {mre:.4f} against strata's reference; "
              f"over the sphere, mean {100 * rel[0]:+.1f} % / {100 * rel[1]:+.1f} % / {100 * rel[2]:+.1f} % (R/G/B)",
              flush=True)
        imgs.append(img[..., :3])
        errs.append(heat(e))
    top = np.concatenate([ra[..., :3], gap] + sum(([x, gap] for x in imgs), [])[:-1], axis=1)
    bot = np.concatenate([heat(eab), gap] + sum(([x, gap] for x in errs), [])[:-1], axis=1)
    save(np.concatenate([top, np.ones((gap.shape[1], top.shape[1], 3), np.float32), bot], axis=0), out, "approximations")
    (out / "compare.json").write_text(json.dumps(res, indent=1))
    return res


def sphere_mask(size):
    """Pixels of the sphere in the sphere scene's camera (those the sphere
    covers, found by rendering its depth once)."""
    d = base_scene(size, size, 1, sun=None, rfilter="box")
    d["integrator"] = {"type": "aov", "aovs": "dd:depth"}
    d["sphere"] = {"type": "sphere", "radius": 1.0, "bsdf": {"type": "diffuse"}}
    with symbolic_mode():
        z = np.array(mi.render(mi.load_dict(d), seed=0))[..., 0]
    return z > 0


def main():
    global TINY
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--all", action="store_true")
    ap.add_argument("--furnace", action="store_true")
    ap.add_argument("--table", action="store_true")
    ap.add_argument("--subjects", nargs="*")
    ap.add_argument("--compare", action="store_true")
    ap.add_argument("--out", default=str(ROOT / "docs" / "gallery" / "paper"))
    ap.add_argument("--spp-scale", type=float, default=1.0)
    ap.add_argument("--table-size", type=int, default=128)
    ap.add_argument("--table-spp", type=int, default=16)
    ap.add_argument("--turns", type=int, default=3)
    ap.add_argument("--compare-size", type=int, default=256)
    ap.add_argument("--compare-spp", type=int, default=16)
    ap.add_argument("--ref-spp", type=int, default=512)
    ap.add_argument("--brute-ref-factor", type=float, default=4.0)
    ap.add_argument("--tiny", action="store_true")
    args = ap.parse_args()
    TINY = args.tiny
    setup()
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    if args.all or args.furnace:
        run_furnace(args, out)
    if args.all or args.table:
        run_table(args, out)
    if args.all or args.subjects is not None:
        run_subjects(args, out, args.subjects or SUBJECTS)
    if args.all or args.compare:
        run_compare(args, out)
    total = time.perf_counter() - t0
    print(f"\nrenders: {sum(t for _, t in LOG):.1f} s; wall clock {total:.1f} s", flush=True)


if __name__ == "__main__":
    main()
