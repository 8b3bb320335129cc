"""The scene of the gallery and the measurements: a sphere on a checkered
ground under a sky-gradient environment (made here, nothing downloaded) and
a sun."""

import numpy as np


def sky(mi, width=64, height=32, ground=(0.12, 0.1, 0.08)):
    """An equirectangular sky: blue at the zenith, pale at the horizon, and
    below it `ground` (a dark brown by default)."""
    v = (np.arange(height) + 0.5) / height  # 0 = zenith, 1 = nadir
    elev = np.cos(np.pi * v)  # +1 up, -1 down
    zenith, horizon, ground = np.array([0.25, 0.4, 0.8]), np.array([0.85, 0.9, 1.0]), np.array(ground)
    t = np.clip(elev, 0, 1)[:, None] ** 0.5
    up = horizon * (1 - t) + zenith * t
    col = np.where(elev[:, None] > 0, up, ground)
    img = np.repeat(col[:, None, :], width, axis=1).astype(np.float32)
    return mi.Bitmap(img)


def scene_dict(mi, bsdf, width=256, height=256, spp=64, max_depth=8, ground=True):
    d = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": max_depth},
        "sensor": {
            "type": "perspective",
            "fov": 32,
            "to_world": mi.ScalarTransform4f().look_at(origin=[0, 1.2, 4.6], target=[0, 0.05, 0], up=[0, 1, 0]),
            "film": {"type": "hdrfilm", "width": width, "height": height, "rfilter": {"type": "gaussian"}},
            "sampler": {"type": "independent", "sample_count": spp},
        },
        "env": {"type": "envmap", "bitmap": sky(mi), "scale": 0.8},
        "sun": {"type": "directional", "direction": [-0.6, -1.0, -0.5], "irradiance": {"type": "rgb", "value": [3.0, 2.9, 2.7]}},
        "sphere": {"type": "sphere", "radius": 1.0, "bsdf": bsdf},
    }
    if ground:
        d["ground"] = {
            "type": "rectangle",
            "to_world": mi.ScalarTransform4f().translate([0, -1, 0]).rotate([1, 0, 0], -90).scale(6),
            "bsdf": {
                "type": "diffuse",
                "reflectance": {
                    "type": "checkerboard",
                    "color0": {"type": "rgb", "value": [0.35, 0.35, 0.35]},
                    "color1": {"type": "rgb", "value": [0.6, 0.6, 0.6]},
                    "to_uv": mi.ScalarTransform4f().scale([8, 8, 1]),
                },
            },
        }
    return d


def normal_map(tx, ty, levels):
    """A normal map (RGB c = (n + 1) / 2, as Mitsuba's normalmap reads it)
    from the slopes `tx`, `ty` of the normal in x and y, each quantized to
    steps of 1 / `levels` so that a wavefront holds a few distinct
    materials."""
    tx = np.round(tx * levels) / levels
    ty = np.round(ty * levels) / levels
    n = np.stack([tx, ty, np.ones_like(tx)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return ((n + 1.0) / 2.0).astype(np.float32)
