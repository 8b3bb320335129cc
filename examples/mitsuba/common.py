"""The scene of the gallery and the measurements: a sphere on a checkered
ground under a sky-gradient environment (made here, nothing downloaded) and
a sun."""

import numpy as np


def sky(mi, width=64, height=32):
    """An equirectangular sky: blue at the zenith, pale at the horizon, a
    dark brown ground."""
    v = (np.arange(height) + 0.5) / height  # 0 = zenith, 1 = nadir
    elev = np.cos(np.pi * v)  # +1 up, -1 down
    zenith, horizon, ground = np.array([0.25, 0.4, 0.8]), np.array([0.85, 0.9, 1.0]), np.array([0.12, 0.1, 0.08])
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
