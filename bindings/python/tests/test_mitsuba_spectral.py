"""The Mitsuba 3 plugin in Mitsuba's spectral variants (scalar_spectral, llvm_ad_spectral).

Mitsuba hands a BSDF four wavelengths per path; strata's walks carry three
(one where an IOR varies). The plugin's eval answers all four (two strata
calls, or four for a dispersive stack); its sample keeps the first call's
wavelengths with weight 4/3 (4 for a dispersive stack) and gives the others
0, which is unbiased because Mitsuba's four wavelengths have one marginal
distribution (``sample_shifted``). The pointwise tests check eval against
Mitsuba's own ``roughconductor``, ``roughdielectric`` and ``diffuse`` at the
wavelengths Mitsuba samples, to 1e-3 relative; the renders check sample's
weighting against the built-in BSDFs with the block criterion of
test_mitsuba.py.
"""

import math

import numpy as np
import pytest

mi = pytest.importorskip("mitsuba")
dr = pytest.importorskip("drjit")

from test_mitsuba import Z_MAX, compare, material, use_variant  # noqa: E402

# Copper-like η and k, tabulated over Mitsuba's range (360-830 nm), linear
# between samples in both strata and Mitsuba (an irregular spectrum).
NM = [360, 450, 520, 600, 700, 830]
ETA = [1.3, 1.15, 1.0, 0.35, 0.21, 0.26]
K = [2.0, 2.4, 2.6, 3.0, 4.2, 5.4]
RHO = [0.1, 0.25, 0.5, 0.7, 0.8, 0.6]


def table(values):
    return f"{{ nm = {NM}, values = {values} }}"


def spectrum(values):
    return {"type": "spectrum", "value": list(zip(map(float, NM), map(float, values)))}


CONDUCTOR = (
    f'[[layers]]\ninterface = {{ kind = "conductor", eta = {table(ETA)}, k = {table(K)}, '
    'roughness = 0.3, shadowing = "separable" }\n'
)
GLASS = '[[layers]]\ninterface = { kind = "dielectric", ior = 1.5, roughness = 0.3, shadowing = "separable" }\n'
LAMBERT = f'[[layers]]\ninterface = {{ kind = "diffuse", albedo = {table(RHO)} }}\n'
CASES = {
    "roughconductor": (
        CONDUCTOR,
        {"type": "roughconductor", "distribution": "ggx", "alpha": 0.3, "eta": spectrum(ETA), "k": spectrum(K)},
    ),
    "roughdielectric": (
        GLASS,
        {"type": "roughdielectric", "distribution": "ggx", "alpha": 0.3, "int_ior": 1.5, "ext_ior": 1.0},
    ),
    "diffuse": (LAMBERT, {"type": "diffuse", "reflectance": spectrum(RHO)}),
}

# A rough dielectric whose IOR varies: n = A + B / λ² (λ in µm).
CAUCHY = (1.5, 0.02)
DISPERSIVE = (
    f'[[layers]]\ninterface = {{ kind = "dielectric", ior = {{ cauchy = [{CAUCHY[0]}, {CAUCHY[1]}] }}, '
    'roughness = 0.3, shadowing = "separable" }\n'
)


def si_at(wi, nm):
    si = mi.SurfaceInteraction3f()
    si.wi = wi
    si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
    si.wavelengths = mi.Spectrum(*nm)
    return si


def sampled_wavelengths(rng):
    """Four wavelengths as Mitsuba's spectral sensors sample them."""
    nm, _ = mi.sample_rgb_spectrum(mi.sample_shifted(float(rng.random())))
    return [float(nm[i]) for i in range(4)]


def pairs(rng, count):
    """Random direction pairs, neither grazing (|cos| >= 0.05)."""
    while count:
        wi, wo = rng.normal(size=3), rng.normal(size=3)
        wi, wo = wi / np.linalg.norm(wi), wo / np.linalg.norm(wo)
        if min(abs(wi[2]), abs(wo[2])) >= 0.05:
            count -= 1
            yield mi.Vector3f(*wi), mi.Vector3f(*wo)


@pytest.mark.parametrize("case", list(CASES))
def test_eval_equals_builtin_at_mitsubas_wavelengths(tmp_path, case):
    """A one-interface stack's eval is exact (its first-order term), so at
    each of the four wavelengths Mitsuba samples the plugin equals the
    built-in BSDF to 1e-3 relative, in both transport modes."""
    use_variant("scalar_spectral")
    text, builtin = CASES[case]
    s = mi.load_dict({"type": "strata", "filename": material(tmp_path, text)})
    b = mi.load_dict(builtin)
    rng = np.random.default_rng(5)
    checked = 0
    for mode in (mi.TransportMode.Radiance, mi.TransportMode.Importance):
        ctx = mi.BSDFContext(mode)
        for wi, wo in pairs(rng, 60):
            si = si_at(wi, sampled_wavelengths(rng))
            vs, vb = s.eval(ctx, si, wo), b.eval(ctx, si, wo)
            assert isinstance(vs, mi.Spectrum)
            for c in range(4):
                assert abs(vs[c] - vb[c]) <= 1e-3 * abs(vb[c]) + 1e-7, (mode, si.wavelengths, wi, wo, c, vs, vb)
            checked += vb[0] > 0
            assert s.pdf(ctx, si, wo) == s.eval_pdf(ctx, si, wo)[1]
    assert checked > 20
    if case != "roughdielectric":  # the others vary with wavelength, and so must the answers
        si = si_at(mi.Vector3f(0, 0, 1), [400, 500, 600, 700])
        v = s.eval(mi.BSDFContext(), si, mi.Vector3f(0, 0, 1))
        assert len({round(v[c], 6) for c in range(4)}) == 4, v


def test_a_dispersive_stack_answers_each_wavelength_at_its_ior(tmp_path):
    """Where the IOR varies each wavelength is its own strata call: the
    plugin's value at λ equals Mitsuba's roughdielectric at n(λ). Light
    arrives from above: reflection inside the glass near the critical angle
    of total internal reflection is ill-conditioned in float32."""
    use_variant("scalar_spectral")
    s = mi.load_dict({"type": "strata", "filename": material(tmp_path, DISPERSIVE)})
    rng = np.random.default_rng(8)
    ctx = mi.BSDFContext()
    for wi, wo in pairs(rng, 24):
        if wi.z < 0:
            continue
        nm = sampled_wavelengths(rng)
        si = si_at(wi, nm)
        vs = s.eval(ctx, si, wo)
        for c in range(4):
            n = CAUCHY[0] + CAUCHY[1] / (nm[c] / 1000.0) ** 2
            b = mi.load_dict({"type": "roughdielectric", "distribution": "ggx", "alpha": 0.3, "int_ior": n, "ext_ior": 1.0})
            vb = b.eval(ctx, si, wo)[c]
            assert abs(vs[c] - vb) <= 1e-3 * abs(vb) + 1e-7, (nm, c, n, vs, vb)


@pytest.mark.parametrize("text,kept", [(CONDUCTOR, 3), (DISPERSIVE, 1)])
def test_sample_keeps_the_first_calls_wavelengths(tmp_path, text, kept):
    """sample's weight at the kept wavelengths is strata's weight at them
    (the same walk: its key is the sampler's numbers hashed) times 4/kept,
    and 0 at the others; its pdf is pdf's at the kept wavelengths."""
    from strata_bsdf import Bsdf

    sm = use_variant("scalar_spectral")
    s = mi.load_dict({"type": "strata", "filename": material(tmp_path, text)})
    lib = Bsdf.from_toml(text, transport="importance")  # Mitsuba's radiance mode
    ctx = mi.BSDFContext()
    rng = np.random.default_rng(3)
    wi = np.array([[0.3, -0.2, 0.93]], np.float32)
    wi /= np.linalg.norm(wi)
    sampled = 0
    for _ in range(40):
        nm = sampled_wavelengths(rng)
        si = si_at(mi.Vector3f(*wi[0]), nm)
        u = rng.random(3).astype(np.float32)
        bs, w = s.sample(ctx, si, float(u[0]), mi.Point2f(float(u[1]), float(u[2])))
        key = np.array([sm.sample_key(*map(float, u))], np.uint64)
        group = np.array([nm[:3] if kept == 3 else [nm[0]] * 3], np.float32)
        wo, weight, pdf, flags = lib.sample(wi, key, wavelengths=group)
        assert bs.pdf == pytest.approx(float(pdf[0]), rel=1e-6)
        if flags[0] == 0:
            continue
        sampled += 1
        np.testing.assert_allclose(list(bs.wo), wo[0], rtol=1e-6)
        for c in range(4):
            want = weight[0][c] * 4 / kept if c < kept else 0.0
            assert w[c] == pytest.approx(want, rel=1e-6, abs=1e-9), (c, nm, w, want)
        assert bs.pdf == pytest.approx(s.pdf(ctx, si, bs.wo), rel=1e-6)
    assert sampled > 20


def test_coloured_textures_are_refused_in_spectral_variants(tmp_path):
    use_variant("scalar_spectral")
    d = {
        "type": "strata",
        "filename": material(tmp_path, LAMBERT),
        "param:layers[0]:interface:albedo": {"type": "rgb", "value": [0.2, 0.4, 0.6]},
    }
    with pytest.raises(Exception, match="coloured texture"):
        mi.load_dict(d)


@pytest.mark.parametrize("case", ["roughconductor", "diffuse"])
def test_renders_agree_with_builtin_in_llvm_ad_spectral(tmp_path, case):
    """Renders with sample's kept wavelengths (and eval's four) against the
    built-in BSDF: the block criterion and the image means of test_mitsuba.py
    (within Z_MAX standard errors and 1 %)."""
    use_variant("llvm_ad_spectral")
    text, builtin = CASES[case]
    width, height, spp, k = 37, 23, 96, 4

    def renders(bsdf, seeds):
        from test_mitsuba import scene

        s = scene(bsdf, width, height, spp)
        return np.stack([np.array(mi.render(s, seed=int(j)), dtype=np.float64) for j in seeds])

    a = renders({"type": "strata", "filename": material(tmp_path, text)}, range(k))
    b = renders(builtin, range(100, 100 + k))
    assert np.isfinite(a).all()
    z, mean_s, mean_r = compare(a, b)
    n_px = a[0].size
    se_mean = math.sqrt((a.var(axis=0, ddof=1).sum() + b.var(axis=0, ddof=1).sum()) / (n_px * n_px * k))
    print(f"{case}: mean strata {mean_s:.5f} builtin {mean_r:.5f}, +- {se_mean:.5f}, max |z| {z.max():.2f}")
    assert abs(mean_s - mean_r) < Z_MAX * se_mean
    assert se_mean / mean_r < 0.0025, "too few samples for the 1 % criterion"
    assert abs(mean_s / mean_r - 1) < 0.01
    assert z.max() < Z_MAX, (z.max(), np.unravel_index(z.argmax(), z.shape))


def test_polarized_variants_are_refused(tmp_path):
    use_variant("scalar_spectral_polarized")
    with pytest.raises(Exception, match="polarized variants are not supported"):
        mi.load_dict({"type": "strata", "filename": material(tmp_path, LAMBERT)})
