"""The Mitsuba 3 plugin against Mitsuba's built-in BSDFs, in scalar_rgb and llvm_ad_rgb.

Agreement criterion (per case, variant and image size): the strata and the
built-in images are each the average of K independent renders (different
seeds; every render is deterministic, so the test is too). For every 8x8
block of pixels (full blocks only) and channel, the standard error of the
block mean is estimated from the spread of the K renders, pixel by pixel
(the sum of the per-pixel sample variances over the block's P pixels,
divided by P^2 K: 64 (K - 1) degrees of freedom), and the difference of the
two block means must be within Z_MAX = 5 combined standard errors (blocks
with zero variance in both, pure background, must agree to 1e-5 relative).
Z_MAX is 5, not 3, because per-pixel variances from K = 4 renders are
themselves noisy where rare bright paths (sun highlights) dominate. The
image means must agree within Z_MAX combined standard errors (estimated in
the same way) and, where those standard errors are below 0.25 % of the mean
(every llvm_ad_rgb configuration, and the scalar_rgb diffuse and conductor),
to 1 %.
"""

import math

import numpy as np
import pytest

mi = pytest.importorskip("mitsuba")
dr = pytest.importorskip("drjit")

Z_MAX = 5.0
BLOCK = 8

LAMBERT = '[[layers]]\ninterface = { kind = "diffuse", albedo = 0.7 }\n'
ETA, K = [0.2, 0.92, 1.1], [3.9, 2.45, 2.2]
CONDUCTOR = (
    '[[layers]]\ninterface = { kind = "conductor", eta = [0.2, 0.92, 1.1], k = [3.9, 2.45, 2.2], '
    'roughness = 0.3, shadowing = "separable" }\n'
)
GLASS = '[[layers]]\ninterface = { kind = "dielectric", ior = 1.5, roughness = 0.3, shadowing = "separable" }\n'


def rgb(v):
    return {"type": "rgb", "value": v}


CASES = {
    "diffuse": (LAMBERT, {"type": "diffuse", "reflectance": rgb([0.7, 0.7, 0.7])}),
    "roughconductor": (
        CONDUCTOR,
        {"type": "roughconductor", "distribution": "ggx", "alpha": 0.3, "eta": rgb(ETA), "k": rgb(K)},
    ),
    "roughdielectric": (
        GLASS,
        {"type": "roughdielectric", "distribution": "ggx", "alpha": 0.3, "int_ior": 1.5, "ext_ior": 1.0},
    ),
}


def use_variant(name):
    if name not in mi.variants():
        pytest.skip(f"Mitsuba variant {name} not available")
    mi.set_variant(name)
    import strata_bsdf.mitsuba as sm

    sm.register()
    if not name.startswith("scalar"):
        sm.enable_evaluated_mode()
    return sm


def scene(bsdf, width, height, spp):
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


def renders(bsdf, width, height, spp, seeds):
    s = scene(bsdf, width, height, spp)
    return np.stack([np.array(mi.render(s, seed=int(k)), dtype=np.float64) for k in seeds])


def block_stats(imgs):
    """Per 8x8 block and channel: the mean over the K renders and its standard error."""
    k, h, w, c = imgs.shape
    hb, wb = h // BLOCK, w // BLOCK
    x = imgs[:, : hb * BLOCK, : wb * BLOCK, :].reshape(k, hb, BLOCK, wb, BLOCK, c)
    mean = x.mean(axis=(0, 2, 4))
    var_px = x.var(axis=0, ddof=1)  # (hb, B, wb, B, c)
    p = BLOCK * BLOCK
    se = np.sqrt(var_px.sum(axis=(1, 3)) / (p * p * k))
    return mean, se


def compare(strata_imgs, ref_imgs):
    ms, ss = block_stats(strata_imgs)
    mr, sr = block_stats(ref_imgs)
    se = np.sqrt(ss**2 + sr**2)
    diff = np.abs(ms - mr)
    flat = se == 0
    assert np.all(diff[flat] <= 1e-5 * np.abs(mr[flat]) + 1e-7), "background blocks differ"
    z = np.where(flat, 0.0, diff / np.where(flat, 1.0, se))
    return z, strata_imgs.mean(), ref_imgs.mean()


def material(tmp_path, text):
    p = tmp_path / f"m{abs(hash(text))}.toml"
    p.write_text(text)
    return str(p)


# (variant, width, height, spp, renders per side)
CONFIGS = [
    ("scalar_rgb", 23, 15, 128, 4),
    ("llvm_ad_rgb", 37, 23, 96, 4),
    ("llvm_ad_rgb", 61, 41, 64, 4),
    ("llvm_ad_rgb", 53, 19, 96, 4),
]


@pytest.mark.parametrize("variant,width,height,spp,k", CONFIGS, ids=[f"{c[0]}-{c[1]}x{c[2]}" for c in CONFIGS])
@pytest.mark.parametrize("case", list(CASES))
def test_agrees_with_builtin(tmp_path, case, variant, width, height, spp, k):
    use_variant(variant)
    text, builtin = CASES[case]
    strata = {"type": "strata", "filename": material(tmp_path, text)}
    a = renders(strata, width, height, spp, range(k))
    b = renders(builtin, width, height, spp, range(100, 100 + k))
    assert a.shape == (k, height, width, 3)
    assert np.isfinite(a).all()
    z, mean_s, mean_r = compare(a, b)
    # Standard error of each image mean, from the per-pixel spread of its K renders.
    n_px = a[0].size
    se_mean = math.sqrt((a.var(axis=0, ddof=1).sum() + b.var(axis=0, ddof=1).sum()) / (n_px * n_px * k))
    rel_se = se_mean / mean_r
    print(f"{case} {variant} {width}x{height}: mean strata {mean_s:.5f} builtin {mean_r:.5f} "
          f"({100 * (mean_s / mean_r - 1):+.3f} % +- {100 * rel_se:.3f} %), max |z| {z.max():.2f} "
          f"over {z.size} block-channels")
    assert abs(mean_s - mean_r) < Z_MAX * se_mean
    if variant != "scalar_rgb":
        assert rel_se < 0.0025, "too few samples for the 1 % criterion"
    if rel_se < 0.0025:
        assert abs(mean_s / mean_r - 1) < 0.01
    assert z.max() < Z_MAX, (z.max(), np.unravel_index(z.argmax(), z.shape))


@pytest.mark.parametrize("variant,width,height", [("scalar_rgb", 13, 9), ("llvm_ad_rgb", 47, 29)])
def test_coated_copper_is_deterministic(materials, variant, width, height):
    use_variant(variant)
    bsdf = {"type": "strata", "filename": str(materials / "coated_copper.toml"), "samples": 2, "seed": 3}
    assert "samples=2, seed=3" in str(mi.load_dict(bsdf))
    s = scene(bsdf, width, height, 4)
    a = np.array(mi.render(s, seed=7))
    b = np.array(mi.render(scene(bsdf, width, height, 4), seed=7))
    assert np.isfinite(a).all()
    np.testing.assert_array_equal(a, b)
    c = np.array(mi.render(s, seed=8))
    assert not np.array_equal(a, c)
    # strata's own seed changes the walks too.
    d = np.array(mi.render(scene(dict(bsdf, seed=4), width, height, 4), seed=7))
    assert not np.array_equal(a, d)
    # The sphere is lit: copper is reddish.
    centre = a[height // 2 - 2 : height // 2 + 2, width // 2 - 2 : width // 2 + 2].mean(axis=(0, 1))
    assert centre[0] > centre[2] > 0


def si_with(wi):
    si = mi.SurfaceInteraction3f()
    si.wi = wi
    si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
    return si


def test_plugin_scalar_calls(tmp_path):
    """eval includes |cos wo|, the frame is the local one, eval_pdf and pdf agree,
    transmission sets eta and the transport mode picks the adjoint."""
    use_variant("scalar_rgb")
    lam = mi.load_dict({"type": "strata", "filename": material(tmp_path, LAMBERT)})
    ctx = mi.BSDFContext()
    wi = mi.Vector3f(0.3, 0.2, math.sqrt(1 - 0.13))
    wo = mi.Vector3f(-0.6, 0.0, 0.8)
    si = si_with(wi)
    v = lam.eval(ctx, si, wo)
    assert abs(v[0] - 0.7 / math.pi * 0.8) < 1e-6
    v2, p = lam.eval_pdf(ctx, si, wo)
    assert list(v2) == list(v) and p == lam.pdf(ctx, si, wo) and p > 0
    assert lam.eval(ctx, si, mi.Vector3f(0, 0.6, -0.8))[0] == 0  # opaque: nothing below
    assert lam.flags() & int(mi.BSDFFlags.DiffuseReflection)
    assert not lam.flags() & int(mi.BSDFFlags.Transmission)

    glass = mi.load_dict({"type": "strata", "filename": material(tmp_path, GLASS)})
    assert glass.flags() & int(mi.BSDFFlags.GlossyTransmission)
    assert glass.flags() & int(mi.BSDFFlags.BackSide)
    seen = {}
    for i in range(400):
        for z in (0.8, -0.8):
            u = ((i * 0.618034) % 1.0, (i * 0.754878) % 1.0, (i * 0.569840) % 1.0)
            bs, w = glass.sample(ctx, si_with(mi.Vector3f(0.6, 0, z)), u[0], mi.Point2f(u[1], u[2]))
            if bs.pdf == 0:
                continue
            trans = mi.has_flag(bs.sampled_type, mi.BSDFFlags.Transmission)
            assert (bs.wo[2] * z < 0) == trans
            if trans:
                seen[z] = bs.eta
            else:
                assert bs.eta == 1
            assert mi.has_flag(bs.sampled_type, mi.BSDFFlags.Glossy)
    assert abs(seen[0.8] - 1.5) < 1e-6 and abs(seen[-0.8] - 1 / 1.5) < 1e-6
    # Camera paths (radiance) take the adjoint of strata's radiance BSDF:
    # leaving the glass towards the viewer, radiance loses (1/1.5)^2.
    si = si_with(mi.Vector3f(0.2, 0.1, 0.9))
    wo = mi.Vector3f(-0.1, 0.0, -0.95)
    rad = glass.eval(ctx, si, wo)
    ictx = mi.BSDFContext(mi.TransportMode.Importance)
    imp = glass.eval(ictx, si, wo)
    assert rad[0] > 0 and abs(rad[0] * 2.25 - imp[0]) < 1e-5 * imp[0]


def test_pdf_samples_property(materials):
    """``pdf_samples`` fixes the density walks of the plugin's pdf: it is the
    Python Bsdf's pdf with that count, bit for bit, and differs from the
    default rule's; 0 is refused."""
    use_variant("scalar_rgb")
    from strata_bsdf import Bsdf

    path = str(materials / "coated_copper.toml")
    d = {"type": "strata", "filename": path}
    default, fixed = mi.load_dict(d), mi.load_dict(dict(d, pdf_samples=4))
    assert "pdf_samples=4" in str(fixed) and "pdf_samples=None" in str(default)
    ctx = mi.BSDFContext()  # a camera path: strata's importance transport
    wi, wo = (0.3, 0.2, math.sqrt(1 - 0.13)), (-0.6, 0.0, 0.8)
    si = si_with(mi.Vector3f(*wi))
    a, b = np.array([wi], np.float32), np.array([wo], np.float32)
    # Camera paths run strata's importance transport, light paths its radiance.
    modes = (("importance", ctx), ("radiance", mi.BSDFContext(mi.TransportMode.Importance)))
    for plugin, n in ((fixed, 4), (default, None)):
        for transport, c in modes:
            want = Bsdf.from_path(path, transport=transport, pdf_samples=n).pdf(a, b)[0]
            got = plugin.pdf(c, si, mi.Vector3f(*wo))
            assert got == float(want) and got > 0, (n, transport, got, want)
    assert fixed.pdf(ctx, si, mi.Vector3f(*wo)) != default.pdf(ctx, si, mi.Vector3f(*wo))
    with pytest.raises(Exception, match="pdf_samples = 0"):
        mi.load_dict(dict(d, pdf_samples=0))
    # A rule by name: "tight" is the Python Bsdf's, and not the default's.
    tight = mi.load_dict(dict(d, pdf_samples="tight"))
    assert "pdf_samples='tight'" in str(tight)
    want = Bsdf.from_path(path, transport="importance", pdf_samples="tight").pdf(a, b)[0]
    got = tight.pdf(ctx, si, mi.Vector3f(*wo))
    assert got == float(want) and got != default.pdf(ctx, si, mi.Vector3f(*wo))
    with pytest.raises(Exception, match="pdf_samples = 'loose'"):
        mi.load_dict(dict(d, pdf_samples="loose"))
    # A count that is not a whole number is named, not truncated.
    with pytest.raises(Exception, match=r"samples = 1\.5: expected a whole number"):
        mi.load_dict(dict(d, samples=1.5))
    with pytest.raises(Exception, match=r"pdf_samples = 4\.5: expected None"):
        mi.load_dict(dict(d, pdf_samples=4.5))


def test_config_property(materials):
    """``config`` applies the library's settings as text, after the other
    properties: ``pdf_walks=4`` gives the pdf of ``pdf_samples=4`` bit for
    bit, in both transport modes; a bad setting names the key and value."""
    use_variant("scalar_rgb")
    path = str(materials / "coated_copper.toml")
    d = {"type": "strata", "filename": path}
    by_text = mi.load_dict(dict(d, config="pdf_walks=4"))
    by_property = mi.load_dict(dict(d, pdf_samples=4))
    default = mi.load_dict(d)
    wi, wo = (0.3, 0.2, math.sqrt(1 - 0.13)), (-0.6, 0.0, 0.8)
    si = si_with(mi.Vector3f(*wi))
    for c in (mi.BSDFContext(), mi.BSDFContext(mi.TransportMode.Importance)):
        got = by_text.pdf(c, si, mi.Vector3f(*wo))
        assert got == by_property.pdf(c, si, mi.Vector3f(*wo)) and got > 0
        assert got != default.pdf(c, si, mi.Vector3f(*wo))
    with pytest.raises(Exception, match="rr_threshold=2"):
        mi.load_dict(dict(d, config="rr_threshold=2"))


def test_delta_samples_are_flagged(materials):
    use_variant("scalar_rgb")
    cc = mi.load_dict({"type": "strata", "filename": str(materials / "clear_coat_lambertian.toml")})
    assert cc.flags() & int(mi.BSDFFlags.DeltaReflection)
    assert cc.flags() & int(mi.BSDFFlags.DiffuseReflection)
    ctx = mi.BSDFContext()
    kinds = set()
    for i in range(300):
        u = ((i * 0.618034) % 1.0, (i * 0.754878) % 1.0, (i * 0.569840) % 1.0)
        bs, w = cc.sample(ctx, si_with(mi.Vector3f(0.3, 0, 0.95)), u[0], mi.Point2f(u[1], u[2]))
        if mi.has_flag(bs.sampled_type, mi.BSDFFlags.DeltaReflection):
            kinds.add("delta")
            assert bs.pdf > 0
            assert abs(bs.wo[0] + 0.3 / math.hypot(0.3, 0.95)) < 1e-5  # the mirror direction
        elif mi.has_flag(bs.sampled_type, mi.BSDFFlags.DiffuseReflection):
            kinds.add("diffuse")
    assert kinds == {"delta", "diffuse"}


def test_symbolic_mode_is_a_clear_error(tmp_path):
    use_variant("llvm_ad_rgb")
    loops, calls = dr.flag(dr.JitFlag.SymbolicLoops), dr.flag(dr.JitFlag.SymbolicCalls)
    dr.set_flag(dr.JitFlag.SymbolicLoops, True)
    dr.set_flag(dr.JitFlag.SymbolicCalls, True)
    try:
        s = scene({"type": "strata", "filename": material(tmp_path, LAMBERT)}, 9, 7, 1)
        with pytest.raises(Exception) as e:
            mi.render(s)
        text = str(e.value) + str(e.value.__cause__) + str(e.value.__context__)
        assert "enable_evaluated_mode()" in text, text
    finally:
        dr.set_flag(dr.JitFlag.SymbolicLoops, loops)
        dr.set_flag(dr.JitFlag.SymbolicCalls, calls)


@pytest.mark.parametrize("case", list(CASES))
def test_eval_equals_builtin_pointwise(tmp_path, case):
    """For a one-interface stack strata's eval is exact (the first-order term),
    so the plugin's eval must equal the built-in BSDF's value, cosine included,
    in both transport modes, for reflection and for transmission either way."""
    use_variant("scalar_rgb")
    text, builtin = CASES[case]
    s = mi.load_dict({"type": "strata", "filename": material(tmp_path, text)})
    b = mi.load_dict(builtin)
    rng = np.random.default_rng(11)
    checked = 0
    for mode in (mi.TransportMode.Radiance, mi.TransportMode.Importance):
        ctx = mi.BSDFContext(mode)
        for _ in range(60):
            wi, wo = rng.normal(size=3), rng.normal(size=3)
            wi, wo = wi / np.linalg.norm(wi), wo / np.linalg.norm(wo)
            if min(abs(wi[2]), abs(wo[2])) < 0.05:
                continue
            si = si_with(mi.Vector3f(*wi))
            vs, vb = s.eval(ctx, si, mi.Vector3f(*wo)), b.eval(ctx, si, mi.Vector3f(*wo))
            for c in range(3):
                assert abs(vs[c] - vb[c]) <= 2e-4 * abs(vb[c]) + 1e-7, (mode, wi, wo, c, vs[c], vb[c])
            checked += vb[0] > 0
    assert checked > 20  # nonzero values compared (opaque stacks: only both-above pairs)


@pytest.mark.parametrize("case", ["diffuse", "roughdielectric"])
def test_light_tracer_agrees_with_builtin(tmp_path, case):
    """Mitsuba's particle tracer (TransportMode.Importance: light paths, strata's
    radiance mode) with strata against the built-in BSDF: image means within
    Z_MAX standard errors (a light tracer is too noisy here for 1 %)."""
    use_variant("llvm_ad_rgb")
    text, builtin = CASES[case]

    def scene_pt(bsdf):
        return mi.load_dict(
            {
                "type": "scene",
                "integrator": {"type": "ptracer", "max_depth": 8},
                "sensor": {
                    "type": "perspective",
                    "fov": 28,
                    "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 5], target=[0, 0, 0], up=[0, 1, 0]),
                    "film": {"type": "hdrfilm", "width": 29, "height": 21, "rfilter": {"type": "box"}},
                    "sampler": {"type": "independent", "sample_count": 256},
                },
                "light": {"type": "sphere", "center": [2, 2, 2], "radius": 0.8,
                          "emitter": {"type": "area", "radiance": rgb([4.0, 4.0, 4.0])}},
                "sphere": {"type": "sphere", "bsdf": bsdf},
                "floor": {"type": "rectangle", "to_world": mi.ScalarTransform4f().translate([0, 0, -1.5]).scale(4),
                          "bsdf": {"type": "diffuse"}},
            }
        )

    k = 4
    strata = scene_pt({"type": "strata", "filename": material(tmp_path, text)})
    ref = scene_pt(builtin)
    a = np.stack([np.array(mi.render(strata, seed=s), dtype=np.float64) for s in range(k)])
    b = np.stack([np.array(mi.render(ref, seed=100 + s), dtype=np.float64) for s in range(k)])
    assert np.isfinite(a).all() and a.mean() > 0
    n_px = a[0].size
    se = math.sqrt((a.var(axis=0, ddof=1).sum() + b.var(axis=0, ddof=1).sum()) / (n_px * n_px * k))
    print(f"ptracer {case}: strata {a.mean():.5f} builtin {b.mean():.5f} ({100 * (a.mean() / b.mean() - 1):+.2f} % "
          f"+- {100 * se / b.mean():.2f} %)")
    assert abs(a.mean() - b.mean()) < Z_MAX * se


def test_jit_calls_answer_each_lane_as_the_module(tmp_path):
    """In llvm_ad_rgb the plugin's sample, eval, pdf and eval_pdf answer each
    lane bit for bit as strata's Bsdf does (keys from sample_keys, eval with
    |cos wo|, eta per side), and zeros (eta 1, type 0) for lanes that are
    inactive, NaN or zero, or whose lobe a type mask excludes."""
    use_variant("llvm_ad_rgb")
    import strata_bsdf.mitsuba as sm
    from strata_bsdf import Bsdf

    path = material(tmp_path, GLASS)
    plugin = mi.load_dict({"type": "strata", "filename": path})
    bsdf = Bsdf.from_path(path, transport="importance")  # camera paths
    rng = np.random.default_rng(5)
    n = 257
    wi, wo = (rng.normal(size=(n, 3)).astype(np.float32) for _ in range(2))
    wi[3], wi[4], wo[5], wo[6] = np.nan, 0, np.inf, 0
    active = rng.random(n) > 0.1
    u = rng.random((3, n)).astype(np.float32)

    def vec(a):
        return mi.Vector3f(*(mi.Float(np.ascontiguousarray(a[:, i])) for i in range(3)))

    def cols(x):
        return tuple(np.array(c, np.float32) for c in (x.x, x.y, x.z))

    def queried(a):
        """Lanes that can be queried, and the directions strata is given."""
        ok = active & np.isfinite(a).all(axis=1) & (a != 0).any(axis=1)
        return ok, tuple(np.ascontiguousarray(np.where(ok, a[:, i], float(i == 2))).astype(np.float32) for i in range(3))

    si = mi.SurfaceInteraction3f()
    si.wi = vec(wi)
    ok_i, wi_q = queried(wi)
    ok_o, wo_q = queried(wo)
    F = mi.BSDFFlags
    for mask in (F.All, F.Reflection):
        ctx = mi.BSDFContext(mi.TransportMode.Radiance, mask)
        bs, weight = plugin.sample(ctx, si, mi.Float(u[0]), mi.Point2f(mi.Float(u[1]), mi.Float(u[2])), mi.Bool(active))
        w_s, wt_s, p_s, fl = bsdf.sample(wi_q, sm.sample_keys(u[0], u[1], u[2]))
        refl = (fl & 1) != 0
        ok = ok_i & (fl != 0) & (refl if mask == F.Reflection else True)
        assert 0 < ok.sum() < n
        for got, want in zip((*cols(bs.wo), *cols(weight), np.array(bs.pdf)), (*w_s, *wt_s, p_s)):
            np.testing.assert_array_equal(got, np.where(ok, want, np.float32(0)))
        eta = np.where(ok & ~refl, np.where(wi_q[2] > 0, np.float32(1.5), 1 / np.float32(1.5)), np.float32(1))
        np.testing.assert_array_equal(np.array(bs.eta), eta)
        want_type = np.where(refl, int(F.GlossyReflection), int(F.GlossyTransmission))
        np.testing.assert_array_equal(np.array(bs.sampled_type), np.where(ok, want_type, 0))

    ctx = mi.BSDFContext()
    ok = ok_i & ok_o
    f, _ = bsdf.eval(wi_q, wo_q)
    p = bsdf.pdf(wi_q, wo_q)
    value = [np.where(ok, c * np.abs(wo_q[2]), np.float32(0)) for c in f]
    v1, p1 = plugin.eval_pdf(ctx, si, vec(wo), mi.Bool(active))
    v2, p2 = plugin.eval(ctx, si, vec(wo), mi.Bool(active)), plugin.pdf(ctx, si, vec(wo), mi.Bool(active))
    for v in (v1, v2):
        for got, want in zip(cols(v), value):
            np.testing.assert_array_equal(got, want)
    for q in (p1, p2):
        np.testing.assert_array_equal(np.array(q), np.where(ok, p, np.float32(0)))
    # A context without smooth lobes asks for nothing: zeros.
    v3, p3 = plugin.eval_pdf(mi.BSDFContext(mi.TransportMode.Radiance, F.Delta), si, vec(wo), mi.Bool(active))
    assert not np.any(cols(v3)) and not np.any(np.array(p3))


def test_sample_keys_match_the_scalar_hash():
    """The vectorized key hash (in place, on uint64 arrays) is the scalar
    variants' hash on Python integers, lane for lane."""
    use_variant("scalar_rgb")
    import strata_bsdf.mitsuba as sm

    u = np.random.default_rng(2).random((3, 200)).astype(np.float32)
    u[:, :3] = [[0, 1, 0.5], [0, 0.999999, 0.25], [0, 0, 0.75]]
    keys = sm.sample_keys(u[0], u[1], u[2])
    assert keys.dtype == np.uint64
    assert keys.tolist() == [sm.sample_key(float(a), float(b), float(c)) for a, b, c in u.T]


def test_overhead_report_runs():
    """bindings/python/benches/plugin_overhead.py (docs/embedding.md), small:
    it runs in both variants, reports its tables and finds the strata and
    built-in image means within 5 standard errors (no time is checked)."""
    import pathlib
    import subprocess
    import sys

    script = pathlib.Path(__file__).resolve().parents[1] / "benches" / "plugin_overhead.py"
    args = ["--width", "31", "--height", "23", "--spp", "16", "--repeat", "3", "--scalar-size", "11", "7",
            "--scalar-spp", "4", "--check"]
    p = subprocess.run([sys.executable, str(script), *args], capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stdout + p.stderr
    for text in ("## llvm_ad_rgb, 31x23 px", "## scalar_rgb, 11x7 px", "| strata |", "| built-in |",
                 "in strata's batch calls", "check: image means agree"):
        assert text in p.stdout, p.stdout
