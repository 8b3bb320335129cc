"""Spectral queries (`wavelengths=`): three wavelengths a query, one per channel."""

import json

import numpy as np
import pytest

from strata_bsdf import Bsdf, QueryError

from test_api import run_cli

# A Lambertian base whose albedo is a tabulated spectrum: f = rho(lambda) / pi,
# rho linear between 400 nm (0.2) and 700 nm (0.8).
DIFFUSE = '[[layers]]\ninterface = { kind = "diffuse", albedo = { nm = [400, 700], values = [0.2, 0.8] } }\n'
GOLD = '[[layers]]\ninterface = { kind = "conductor", preset = "Au", roughness = 0.2 }\n'
GLASS = '[[layers]]\ninterface = { kind = "dielectric", ior = { nd = 1.5168, abbe = 40 }, roughness = 0.2 }\n'


def pairs(n):
    wi = np.tile(np.array([[0.1, 0.0, 1.0]], dtype=np.float32), (n, 1))
    wo = np.tile(np.array([[0.3, 0.2, 0.9]], dtype=np.float32), (n, 1))
    return wi, wo


def test_a_spectral_albedo_answers_at_each_wavelength():
    nm = np.array([[400, 550, 700], [450, 500, 650], [380, 720, 600]], dtype=np.float32)
    wi, wo = pairs(len(nm))
    f, se = Bsdf.from_toml(DIFFUSE).eval(wi, wo, wavelengths=nm)
    rho = 0.2 + 0.6 * (np.clip(nm.astype(np.float64), 400, 700) - 400) / 300
    np.testing.assert_allclose(f, rho / np.pi, rtol=1e-6)
    assert np.all(se == 0)
    # Without wavelengths: the RGB numbers of the spectrum.
    f_rgb, _ = Bsdf.from_toml(DIFFUSE).eval(wi, wo)
    assert not np.allclose(f_rgb, f)


def test_every_verb_takes_wavelengths_and_matches_the_cli(strata_cli, tmp_path):
    path = tmp_path / "gold.toml"
    path.write_text(GOLD)
    nm = np.array([[450, 550, 650], [700, 700, 700]], dtype=np.float32)
    wi, wo = pairs(2)
    b = Bsdf.from_toml(GOLD, samples=4)
    f, _ = b.eval(wi, wo, wavelengths=nm)
    line = json.dumps({"wi": wi[0].tolist(), "wo": wo[0].tolist()}) + "\n"
    for k, w in enumerate(["450,550,650", "700"]):
        cli = run_cli(strata_cli, ["eval", "--material", str(path), "--samples", "4", "--wavelengths", w], line)
        got = f[k] if k == 0 else f[k][:1]
        np.testing.assert_allclose(got, cli[0]["f"], rtol=1e-6)
    # Gold is redder at longer wavelengths.
    assert f[0][0] < 0.6 * f[0][2]
    f2, _, pdf = b.eval_pdf(wi, wo, wavelengths=nm)
    np.testing.assert_array_equal(f2, f)
    np.testing.assert_array_equal(pdf, b.pdf(wi, wo, wavelengths=nm))
    wo_s, weight, pdf_s, flags = b.sample(wi, wavelengths=nm)
    assert weight.shape == (2, 3) and np.all(flags != 0)
    np.testing.assert_array_equal(pdf_s, b.pdf(wi, wo_s, wavelengths=nm))
    r, t, r_se, t_se = b.albedo(wi, 64, wavelengths=nm)
    assert r.shape == (2, 3) and np.all(t == 0) and r[0][0] < r[0][2]
    p, p_se = b.pdf_unbiased(wi, wo, 16, wavelengths=nm)
    assert p.shape == (2,)


def test_an_rgb_param_is_read_at_the_wavelengths_as_the_cli_reads_a_set(strata_cli, tmp_path):
    path = tmp_path / "diffuse.toml"
    path.write_text(DIFFUSE)
    rgb = np.array([[0.8, 0.3, 0.1]], dtype=np.float32)
    nm = np.array([[450, 550, 650]], dtype=np.float32)
    wi, wo = pairs(1)
    params = {"layers[0].interface.albedo": rgb}
    f, _ = Bsdf.from_toml(DIFFUSE).eval(wi, wo, params=params, wavelengths=nm)
    line = json.dumps({"wi": wi[0].tolist(), "wo": wo[0].tolist(), "set": {"layers[0].interface.albedo": [0.8, 0.3, 0.1]}})
    cli = run_cli(strata_cli, ["eval", "--material", str(path), "--wavelengths", "450,550,650"], line + "\n")
    np.testing.assert_allclose(f[0], cli[0]["f"], rtol=1e-6)
    assert f[0][2] > 2 * f[0][0]


@pytest.mark.parametrize(
    "nm,exc,words",
    [
        (np.array([[450, 550, 650]], dtype=np.float64), ValueError, ["wavelengths", "float32", "(2, 3)"]),
        (np.array([450, 550, 650, 700, 600, 500], dtype=np.float32), ValueError, ["(2, 3)", "shape (6,)"]),
        ([[450, 550, 650], [450, 550, 650]], TypeError, ["wavelengths", "list"]),
    ],
)
def test_bad_wavelength_arrays_name_the_shape(nm, exc, words):
    wi, wo = pairs(2)
    with pytest.raises(exc) as e:
        Bsdf.from_toml(GOLD).eval(wi, wo, wavelengths=nm)
    for w in words:
        assert w in str(e.value), str(e.value)


def test_bad_wavelengths_name_the_query():
    wi, wo = pairs(2)
    nm = np.array([[450, 550, 650], [500, np.nan, 600]], dtype=np.float32)
    with pytest.raises(QueryError) as e:
        Bsdf.from_toml(GOLD).eval(wi, wo, wavelengths=nm)
    assert e.value.index == 1 and "nan" in str(e.value).lower(), str(e.value)
    # A dispersive IOR refracts at one wavelength a walk.
    nm = np.array([[500, 500, 500], [450, 550, 650]], dtype=np.float32)
    with pytest.raises(QueryError) as e:
        Bsdf.from_toml(GLASS).eval(wi, wo, wavelengths=nm)
    assert e.value.index == 1 and "layers[0].interface.ior" in str(e.value), str(e.value)
    f, _ = Bsdf.from_toml(GLASS).eval(wi, wo, wavelengths=np.array([[450] * 3, [650] * 3], dtype=np.float32))
    assert f[0][0] != f[1][0]


def test_a_bad_param_with_wavelengths_names_the_param():
    # The material's own spectral columns come after the caller's: an error
    # about a param names that param (a triple for a number here).
    wi, wo = pairs(2)
    nm = np.array([[450, 550, 650]] * 2, dtype=np.float32)
    params = {"layers[0].interface.roughness": np.full((2, 3), 0.2, dtype=np.float32)}
    with pytest.raises(ValueError) as e:
        Bsdf.from_toml(GOLD).eval(wi, wo, params=params, wavelengths=nm)
    assert "layers[0].interface.roughness" in str(e.value) and "(2, 3)" in str(e.value), str(e.value)


def test_non_contiguous_wavelengths_are_refused():
    wi, wo = pairs(2)
    nm = np.asfortranarray(np.array([[450, 550, 650], [500, 600, 700]], dtype=np.float32))
    with pytest.raises(ValueError) as e:
        Bsdf.from_toml(GOLD).eval(wi, wo, wavelengths=nm)
    assert "C-contiguous" in str(e.value), str(e.value)


def test_a_dispersive_prism_splits_light_as_snells_law_says(materials):
    """examples/materials/dispersive_prism.toml: a coat of Abbe number 6 over
    smooth silver tilted under it. The path that refracts in, reflects off
    the tilted silver and refracts out leaves in a direction Snell's law
    gives at each wavelength's IOR (computed here); the median direction of
    sample's glossy (non-delta) samples at 450 nm and at 650 nm is that
    direction, to 0.005, and the two are 0.12 apart."""
    from strata_bsdf import DELTA

    b = Bsdf.from_path(str(materials / "dispersive_prism.toml"))
    assert b.wavelengths_per_walk == 1

    def ior(nm, nd=1.6, abbe=6.0):  # the Abbe form, docs/materials.md
        f, d, c = 0.48613, 0.58756, 0.65627
        bb = (nd - 1) / (abbe * (f**-2 - c**-2))
        return nd - bb / d**2 + bb / (nm / 1000) ** 2

    def snell(wi, n):
        t = np.array([-wi[0] / n, -wi[1] / n, 0.0])  # refracted into the coat
        t[2] = -np.sqrt(1 - t[0] ** 2 - t[1] ** 2)
        m = np.array([-0.5, 0.0, 1.0]) / np.sqrt(1.25)  # the silver's normal
        r = t - 2 * np.dot(t, m) * m
        s = r[:2] * n  # refracted out
        return np.array([s[0], s[1], np.sqrt(1 - s @ s)])

    n = 20_000
    wi = np.array([-0.75, 0.0, np.sqrt(1 - 0.75**2)], np.float32)
    want = {nm: snell(wi.astype(np.float64), ior(nm)) for nm in (450, 650)}
    assert np.linalg.norm(want[450] - want[650]) > 0.1
    for nm, w in want.items():
        wo, _, _, flags = b.sample(
            np.tile(wi, (n, 1)), np.arange(n, dtype=np.uint64), wavelengths=np.full((n, 3), nm, np.float32)
        )
        glossy = (flags != 0) & ((flags & DELTA) == 0)
        assert glossy.sum() > n // 2
        np.testing.assert_allclose(np.median(wo[glossy], axis=0), w, atol=0.005, err_msg=f"{nm} nm")
