"""The Mitsuba plugin's textured parameters (``param:<path>`` properties)."""

import numpy as np
import pytest

mi = pytest.importorskip("mitsuba")
dr = pytest.importorskip("drjit")

from test_mitsuba import material, scene, use_variant  # noqa: E402
from test_params import decimal  # noqa: E402

# A rough coat with a tinted absorber over rough silver: the thickness shows
# as colour depth. (Not a Lambertian base: there `auto` answers a uniform
# material without walks, by a constant of its coat and layer, but textured
# thicknesses and extinctions by the walks, which agree with it in
# expectation only; docs/embedding.md.)
COAT = """
[[layers]]
interface = {{ kind = "dielectric", ior = 1.5, roughness = 0.2 }}
medium = {{ thickness = {thickness}, sigma_t = {sigma_t}, albedo = 0.0 }}
[[layers]]
interface = {{ kind = "conductor", preset = "Ag", roughness = 0.3 }}
"""
TH = "param:layers[0]:medium:thickness"
SIG = "param:layers[0]:medium:sigma_t"


def coat(thickness=0.5, sigma_t=(0.25, 1.0, 2.0)):
    return COAT.format(thickness=repr(float(thickness)), sigma_t=[float(x) for x in sigma_t])


def render(bsdf, w, h, spp, seed=3):
    return np.array(mi.render(scene(bsdf, w, h, spp), seed=seed))


@pytest.mark.parametrize("variant,w,h,spp", [("scalar_rgb", 9, 7, 4), ("llvm_ad_rgb", 29, 23, 8)])
def test_constant_parameters_render_as_the_material(tmp_path, variant, w, h, spp):
    """A thickness given as a float, as a uniform texture and an RGB sigma_t render
    bit for bit what the material with those values renders."""
    use_variant(variant)
    ref = render({"type": "strata", "filename": material(tmp_path, coat(1.25, (0.5, 1.5, 3.0)))}, w, h, spp)
    base = material(tmp_path, coat())
    for th in (1.25, {"type": "uniform", "value": 1.25}):
        got = render({"type": "strata", "filename": base, TH: th,
                      SIG: {"type": "rgb", "value": [0.5, 1.5, 3.0]}}, w, h, spp)
        np.testing.assert_array_equal(got, ref)
    assert not np.array_equal(render({"type": "strata", "filename": base}, w, h, spp), ref)
    b = mi.load_dict({"type": "strata", "filename": base, TH: 1.25})
    assert "layers[0].medium.thickness=UniformSpectrum" in str(b)


def pixel_regions(checker, w, h):
    """Per pixel: the checker value at its centre if its four corners and
    centre all hit the sphere in the same checker cell, else NaN."""
    use_variant("llvm_ad_rgb")
    s = scene({"type": "diffuse"}, w, h, 1)
    sensor = s.sensors()[0]
    vals = []
    for dx, dy in ((0.5, 0.5), (0.001, 0.001), (0.999, 0.001), (0.001, 0.999), (0.999, 0.999)):
        ys, xs = np.meshgrid(np.arange(h), np.arange(w), indexing="ij")
        pos = mi.Point2f(((xs + dx) / w).ravel().astype(np.float32), ((ys + dy) / h).ravel().astype(np.float32))
        ray, _ = sensor.sample_ray(0.0, 0.5, pos, mi.Point2f(0.5, 0.5))
        si = s.ray_intersect(ray)
        v = np.array(checker.eval_1(si, si.is_valid()).numpy(), np.float64)
        v[~np.array(si.is_valid().numpy())] = np.nan
        vals.append(v.reshape(h, w))
    vals = np.stack(vals)
    same = np.all(vals == vals[0], axis=0)
    return np.where(same, vals[0], np.nan)


def test_checkerboard_thickness_maps_pixel_by_pixel(tmp_path):
    """A checkerboard thickness: every pixel whose footprint lies in one checker
    cell equals, bit for bit, the render of the uniform material of that cell's
    thickness (same seeds: the same paths), and the two cells differ."""
    use_variant("llvm_ad_rgb")
    w, h, spp = 48, 40, 8
    t0, t1 = 0.1, 2.0
    checker = {"type": "checkerboard", "color0": t0, "color1": t1, "to_uv": mi.ScalarTransform4f().scale([4, 4, 1])}
    region = pixel_regions(mi.load_dict(checker), w, h)
    base = material(tmp_path, coat())
    tex = render({"type": "strata", "filename": base, TH: checker}, w, h, spp)
    # A thickness is written into the rows as the float32 the texture holds
    # (docs/changes.md): the reference materials are given that float.
    a = render({"type": "strata", "filename": material(tmp_path, coat(np.float32(t0)))}, w, h, spp)
    b = render({"type": "strata", "filename": material(tmp_path, coat(np.float32(t1)))}, w, h, spp)
    in0 = region == np.float32(t0)
    in1 = region == np.float32(t1)
    assert in0.sum() > 100 and in1.sum() > 100, (in0.sum(), in1.sum())
    np.testing.assert_array_equal(tex[in0], a[in0])
    np.testing.assert_array_equal(tex[in1], b[in1])
    # A mis-mapped or ignored texture would fail above: the two materials differ
    # on (nearly) every such pixel.
    assert np.mean(np.any(a[in0] != b[in0], axis=-1)) > 0.9
    assert np.mean(np.any(a[in1] != b[in1], axis=-1)) > 0.9


def test_rgb_bitmap_sigma_t_and_errors(tmp_path):
    """An RGB bitmap drives sigma_t (eval, width 3); an invalid texel and an
    unknown path are errors that name the path."""
    use_variant("llvm_ad_rgb")
    base = material(tmp_path, coat())
    data = np.ones((4, 4, 3), np.float32) * np.float32([0.5, 1.5, 3.0])
    bmp = {"type": "bitmap", "bitmap": mi.Bitmap(data), "raw": True, "filter_type": "nearest"}
    got = render({"type": "strata", "filename": base, SIG: bmp}, 21, 17, 4)
    ref = render({"type": "strata", "filename": material(tmp_path, coat(0.5, (0.5, 1.5, 3.0)))}, 21, 17, 4)
    np.testing.assert_array_equal(got, ref)
    with pytest.raises(Exception) as e:
        mi.load_dict({"type": "strata", "filename": base, "param:layers[0]:medium:thicknes": 1.0})
    assert "layers[0].medium.thicknes" in str(e.value) and "unknown medium field" in str(e.value)
    bad = np.ones((4, 4, 1), np.float32)
    bad[:, :2] = -1.0  # mean 0: a valid probe; texels of -1 are not
    s = scene({"type": "strata", "filename": base,
               TH: {"type": "bitmap", "bitmap": mi.Bitmap(bad), "raw": True, "filter_type": "nearest"}}, 9, 7, 1)
    with pytest.raises(Exception) as e:
        mi.render(s)
    text = str(e.value) + str(e.value.__cause__) + str(e.value.__context__)
    assert "set `layers[0].medium.thickness` = -1.0" in text, text


def test_traverse_exposes_the_textures(tmp_path):
    """mi.traverse reaches a param texture's own parameters, and changing them
    changes what the plugin renders (the texture is evaluated at every call)."""
    use_variant("llvm_ad_rgb")
    checker = {"type": "checkerboard", "color0": 0.1, "color1": 2.0}
    s = scene({"type": "strata", "filename": material(tmp_path, coat()), TH: checker}, 17, 13, 4)
    p = mi.traverse(s)
    for c in ("color0", "color1"):
        p[f"sphere.bsdf.{TH}.{c}.value"] = 1.25
    p.update()
    got = np.array(mi.render(s, seed=3))
    ref = render({"type": "strata", "filename": material(tmp_path, coat(1.25))}, 17, 13, 4)
    np.testing.assert_array_equal(got, ref)


NRM = "param:layers[0]:interface:normal"


def test_a_normal_map_tilts_the_coat(tmp_path):
    """A normal texture is a normal map (n = 2c - 1): the flat texel renders bit
    for bit the untilted material, a tilted one the material whose coat has
    that normal."""
    use_variant("llvm_ad_rgb")
    w, h, spp = 29, 23, 8
    base = material(tmp_path, coat())
    flat = render({"type": "strata", "filename": base}, w, h, spp)
    got = render({"type": "strata", "filename": base, NRM: {"type": "rgb", "value": [0.5, 0.5, 1.0]}}, w, h, spp)
    np.testing.assert_array_equal(got, flat)
    c = np.array([0.6, 0.5, 0.9], np.float32)
    # The texel's normal, 2c - 1 in float32, as the number a column sets.
    n = [decimal(x) for x in np.float32(2.0) * c - np.float32(1.0)]
    tilted = coat().replace('roughness = 0.2 }', f"roughness = 0.2, normal = [{n[0]}, {n[1]}, {n[2]}] }}")
    assert "normal" in tilted
    ref = render({"type": "strata", "filename": material(tmp_path, tilted)}, w, h, spp)
    got = render({"type": "strata", "filename": base, NRM: {"type": "rgb", "value": [0.6, 0.5, 0.9]}}, w, h, spp)
    np.testing.assert_array_equal(got, ref)
    assert not np.array_equal(ref, flat)
