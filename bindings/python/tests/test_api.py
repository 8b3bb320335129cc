"""The Python module against the Rust API (through the CLI), and its errors."""

import json
import math
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

import strata_bsdf as sb
from strata_bsdf import Bsdf, MaterialError, QueryError

LAMBERT = '[[layers]]\ninterface = { kind = "diffuse", albedo = 0.7 }\n'
GLASS = '[[layers]]\ninterface = { kind = "dielectric", ior = 1.5, roughness = 0.3 }\n'


def normalized(v):
    """v normalized exactly as strata normalizes (in f64, scaled by the
    largest component first)."""
    d = [float(x) for x in v]
    m = max(abs(x) for x in d)
    s = [x / m for x in d]
    length = math.sqrt(s[0] * s[0] + s[1] * s[1] + s[2] * s[2])
    return [x / length for x in s]


def query_lines(wi, wo):
    """The queries as `strata eval` reads them: a JSON line per pair."""
    return "".join(
        json.dumps({"wi": [float(x) for x in a], "wo": [float(x) for x in b]}) + "\n" for a, b in zip(wi, wo)
    )


def fixed_directions(n, rng, lower=0.0):
    """n unit f32 directions that strata's normalization leaves unchanged
    (so that the CLI, which normalizes its input before the library does
    again, and Python see the same f32 bits). `lower` is the fraction below
    the surface."""
    out = np.empty((n, 3), np.float32)
    for i in range(n):
        v = rng.normal(size=3)
        v[2] = abs(v[2]) + 0.05
        if rng.random() < lower:
            v[2] = -v[2]
        v = np.float32(normalized(v))
        for _ in range(10):
            w = np.float32(normalized(v))
            if np.array_equal(w, v):
                break
            v = w
        else:
            raise AssertionError("no fixed point")
        out[i] = v
    return out


def soa(a):
    return tuple(np.ascontiguousarray(a[:, i]) for i in range(3))


def aos(t):
    return np.stack(t, axis=1)


def run_cli(cli, args, stdin=""):
    r = subprocess.run([str(cli)] + args, input=stdin, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    return [json.loads(line) for line in r.stdout.splitlines() if line.strip()]


@pytest.mark.parametrize(
    "material,lower",
    [("coated_copper.toml", 0.0), ("clear_coat_lambertian.toml", 0.0), ("scattering_slab.toml", 0.4),
     ("three_interfaces.toml", 0.0), ("coated_copper.json", 0.0)],
)
def test_eval_and_pdf_bit_identical_to_cli(strata_cli, materials, material, lower):
    path = materials / material
    rng = np.random.default_rng(7)
    n, samples, seed = 40, 16, 12345
    wi = fixed_directions(n, rng)
    wo = fixed_directions(n, rng, lower)
    lines = query_lines(wi, wo)
    cli = run_cli(strata_cli, ["eval", "--material", str(path), "--samples", str(samples), "--seed", str(seed)], lines)
    assert len(cli) == n
    bsdf = Bsdf.from_path(path, samples=samples, seed=seed)
    # The CLI keys each query by its directions, as an unkeyed call does.
    f, se = bsdf.eval(wi, wo)
    pdf = bsdf.pdf(wi, wo)
    np.testing.assert_array_equal(f, np.array([c["f"] for c in cli], dtype=np.float64).astype(np.float32))
    np.testing.assert_array_equal(se, np.array([c["stderr"] for c in cli], dtype=np.float64).astype(np.float32))
    np.testing.assert_array_equal(pdf, np.array([c["pdf"] for c in cli], dtype=np.float64).astype(np.float32))
    assert np.all(f >= 0) and np.any(f > 0)


def test_fixed_pdf_samples_bit_identical_to_cli(strata_cli, materials):
    # pdf_samples=N fixes the density walks, as `--pdf-samples N` does; the
    # default (None) runs the library's pilot round, as the CLI's default.
    path = materials / "scattering_slab.toml"
    rng = np.random.default_rng(5)
    n, seed = 16, 3
    wi = fixed_directions(n, rng)
    wo = fixed_directions(n, rng)
    lines = query_lines(wi, wo)
    args = ["eval", "--material", str(path), "--samples", "4", "--seed", str(seed), "--pdf-samples", "4"]
    cli = run_cli(strata_cli, args, lines)
    fixed = Bsdf.from_path(path, samples=4, seed=seed, pdf_samples=4).pdf(wi, wo)
    np.testing.assert_array_equal(fixed, np.array([c["pdf"] for c in cli], dtype=np.float64).astype(np.float32))
    rule = Bsdf.from_path(path, samples=4, seed=seed)
    default = rule.pdf(wi, wo)
    assert np.all(default > 0) and np.any(default != fixed)
    # The setting reads back, and survives the with_* copies.
    four = Bsdf.from_path(path, pdf_samples=4)
    assert rule.pdf_samples is None and four.pdf_samples == 4
    assert four.with_transport("importance").with_estimator("uni").pdf_samples == 4
    assert "pdf_samples=4" in repr(four) and "pdf_samples=None" in repr(rule)
    with pytest.raises(ValueError, match="pdf_samples = 0"):
        Bsdf.from_path(path, pdf_samples=0)
    for bad in (-3, 2**64):
        with pytest.raises(ValueError, match=f"pdf_samples = {bad}: expected 1 to"):
            Bsdf.from_path(path, pdf_samples=bad)
    with pytest.raises(ValueError, match=f"pdf_samples = {2**40 + 1}: at most {2**40} walks"):
        Bsdf.from_path(path, pdf_samples=2**40 + 1)
    assert Bsdf.from_path(path, pdf_samples=2**40).pdf_samples == 2**40


def test_pdf_rules_bit_identical_to_cli(strata_cli, materials):
    # pdf_samples names the library's rules ("default", "tight") or sets an
    # adaptive one, (pilot, max, rel_stderr), as `--pdf-samples` does: the
    # same pdfs as the CLI's, bit for bit; "tight" is (8, 128, 0.1) and
    # differs from the default; each reads back as given.
    path = materials / "scattering_slab.toml"
    rng = np.random.default_rng(6)
    n, seed = 16, 3
    wi = fixed_directions(n, rng)
    wo = fixed_directions(n, rng)
    lines = query_lines(wi, wo)
    pdfs = {}
    for arg, flag, back in (
        ("default", "default", None),
        ("adaptive", "adaptive", "adaptive"),
        ((8, 64, 0.15), "8,64,0.15", "adaptive"),
        ("tight", "tight", "tight"),
        ((8, 128, 0.1), "8,128,0.1", "tight"),
        ((4, 24, 0.3), "4,24,0.3", (4, 24, 0.3)),
    ):
        args = ["eval", "--material", str(path), "--samples", "4", "--seed", str(seed), "--pdf-samples", flag]
        cli = np.array([c["pdf"] for c in run_cli(strata_cli, args, lines)], dtype=np.float64).astype(np.float32)
        bsdf = Bsdf.from_path(path, samples=4, seed=seed, pdf_samples=arg)
        np.testing.assert_array_equal(bsdf.pdf(wi, wo), cli, err_msg=flag)
        assert bsdf.pdf_samples == back and f"pdf_samples={back!r}" in repr(bsdf), (flag, bsdf)
        assert bsdf.with_estimator("uni").pdf_samples == back
        pdfs[flag] = cli
    np.testing.assert_array_equal(pdfs["default"], Bsdf.from_path(path, samples=4, seed=seed).pdf(wi, wo))
    assert np.any(pdfs["tight"] != pdfs["default"]) and np.any(pdfs["4,24,0.3"] != pdfs["tight"])
    assert np.any(pdfs["adaptive"] != pdfs["default"]) and np.any(pdfs["adaptive"] != pdfs["tight"])
    for bad, kind, message in (
        ("tighter", ValueError, "pdf_samples = 'tighter': expected None"),
        ((1, 64, 0.1), ValueError, r"pdf_samples = \(1, 64, 0.1\): pilot = 1: expected 2 to"),
        ((8, 4, 0.1), ValueError, r"max = 4: expected pilot \(8\) to"),
        ((8, 64, float("nan")), ValueError, "rel_stderr = NaN"),
        ((8, -1, 0.1), ValueError, "max = -1: expected a number of walks"),
        ((8.5, 64, 0.1), TypeError, "pilot = 8.5: expected a whole number, got float"),
        ((8, 64, float("inf")), ValueError, r"pdf_samples = \(8, 64, inf\): rel_stderr = inf"),
        (1.5, TypeError, r"pdf_samples = 1\.5: expected None \(the library's rule\), a number of walks.*, got float"),
        ([8, 64], TypeError, r"pdf_samples = \[8, 64\]: .*, got list"),
    ):
        with pytest.raises(kind, match=message):
            Bsdf.from_path(path, pdf_samples=bad)


@pytest.mark.parametrize("material", ["coated_copper.toml", "three_interfaces.toml"])
@pytest.mark.parametrize("estimator", ["uni", "bidir", "auto"])
def test_estimators_bit_identical_to_cli(strata_cli, materials, material, estimator):
    path = materials / material
    rng = np.random.default_rng(3)
    n, samples, seed = 12, 32, 7
    wi = fixed_directions(n, rng)
    wo = fixed_directions(n, rng)
    lines = query_lines(wi, wo)
    args = ["eval", "--material", str(path), "--samples", str(samples), "--seed", str(seed), "--estimator", estimator]
    cli = run_cli(strata_cli, args, lines)
    bsdf = Bsdf.from_path(path, samples=samples, seed=seed, estimator=estimator)
    assert bsdf.estimator == estimator
    # Auto runs the bidirectional walks on three interfaces, not on two.
    assert bsdf.bidirectional == (estimator == "bidir" or (estimator == "auto" and material.startswith("three")))
    f, se = bsdf.eval(wi, wo)
    np.testing.assert_array_equal(f, np.array([c["f"] for c in cli], dtype=np.float64).astype(np.float32))
    np.testing.assert_array_equal(se, np.array([c["stderr"] for c in cli], dtype=np.float64).astype(np.float32))
    assert np.all(f >= 0) and np.any(f > 0)
    other = bsdf.with_estimator("uni" if estimator != "uni" else "bidir")
    assert other.estimator != estimator and "estimator=" in repr(other)


def test_bad_estimator_is_a_value_error_naming_it():
    with pytest.raises(ValueError, match="unknown estimator \"both\""):
        Bsdf.from_toml(GLASS, estimator="both")
    with pytest.raises(ValueError, match="expected auto, uni or bidir"):
        Bsdf.from_toml(GLASS).with_estimator("")


@pytest.mark.parametrize("material", ["coated_copper.toml", "scattering_slab.toml"])
def test_unbiased_pdf_bit_identical_to_cli(strata_cli, materials, material):
    path = materials / material
    rng = np.random.default_rng(11)
    n, walks, seed = 12, 64, 5
    wi = fixed_directions(n, rng)
    wo = fixed_directions(n, rng, False)
    lines = query_lines(wi, wo)
    args = ["eval", "--material", str(path), "--samples", "1", "--seed", str(seed)]
    cli = run_cli(strata_cli, args + ["--pdf", "unbiased", "--pdf-samples", str(walks)], lines)
    bsdf = Bsdf.from_path(path, samples=1, seed=seed)
    pdf, se = bsdf.pdf_unbiased(wi, wo, walks)
    np.testing.assert_array_equal(pdf, np.array([c["pdf"] for c in cli], dtype=np.float64).astype(np.float32))
    np.testing.assert_array_equal(se, np.array([c["pdf_stderr"] for c in cli], dtype=np.float64).astype(np.float32))
    assert np.all(pdf >= 0) and np.any(se > 0)
    with pytest.raises(ValueError, match="samples = 0"):
        bsdf.pdf_unbiased(wi, wo, 0)


@pytest.mark.parametrize("material", ["coated_copper.toml", "scattering_slab.toml", "clear_coat_lambertian.toml"])
def test_sample_bit_identical_to_cli(strata_cli, materials, material):
    path = materials / material
    wi = np.array([0.3, -0.2, 0.9], np.float32)
    n, seed = 300, 99
    cli = run_cli(
        strata_cli,
        ["sample", "--material", str(path), "--wi", ",".join(repr(float(x)) for x in wi), "--count", str(n),
         "--seed", str(seed)],
    )
    bsdf = Bsdf.from_path(path, seed=seed)
    # Unkeyed, query k draws sample index k of its direction's key: line k of `strata sample`.
    wo, weight, pdf, flags = bsdf.sample(np.tile(wi, (n, 1)))
    want_wo = np.array([c["wo"] or [0, 0, 0] for c in cli], np.float64).astype(np.float32)
    want_w = np.array([c["weight"] for c in cli], np.float64).astype(np.float32)
    np.testing.assert_array_equal(wo, want_wo)
    np.testing.assert_array_equal(weight, want_w)
    for c, fl in zip(cli, flags):
        if c["wo"] is None:
            assert fl == 0
        else:
            assert bool(fl & sb.REFLECTION) == c["reflection"]
            assert bool(fl & sb.TRANSMISSION) == (not c["reflection"])
            assert bool(fl & sb.DELTA) == c["specular"]
    # The pdf a sample carries is the pdf of its direction.
    live = flags != 0
    np.testing.assert_array_equal(pdf[live], bsdf.pdf(np.tile(wi, (int(live.sum()), 1)), wo[live]))
    assert np.all(pdf[live] > 0) and np.all(pdf[~live] == 0)


@pytest.mark.parametrize("material,theta,phi", [("scattering_slab.toml", 30.0, 20.0),
                                                ("scattering_slab.toml", 120.0, 0.0),
                                                ("coated_copper.toml", 60.0, 45.0)])
def test_albedo_bit_identical_to_cli(strata_cli, materials, material, theta, phi):
    path = materials / material
    n, seed = 5000, 4
    cli = run_cli(strata_cli, ["albedo", "--material", str(path), "--theta", str(theta), "--phi", str(phi),
                               "--samples", str(n), "--seed", str(seed)])[0]
    # The CLI's direction: f64 trigonometry, cast to f32.
    t, p = math.radians(theta), math.radians(phi)
    wi = np.array([[math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t)]], np.float32)
    r, tr, r_se, t_se = Bsdf.from_path(path, seed=seed).albedo(wi, n)
    for got, key in ((r, "R"), (tr, "T"), (r_se, "stderr_R"), (t_se, "stderr_T")):
        np.testing.assert_array_equal(got[0], np.array(cli[key], np.float64).astype(np.float32))
    assert r[0].sum() > 0


def test_soa_and_aos_identical(materials):
    rng = np.random.default_rng(3)
    bsdf = Bsdf.from_path(materials / "scattering_slab.toml", samples=8, seed=5)
    wi = fixed_directions(33, rng)
    wo = fixed_directions(33, rng, 0.5)
    keys = rng.integers(0, 2**63, size=33, dtype=np.uint64)
    f_a, s_a = bsdf.eval(wi, wo, keys)
    f_s, s_s = bsdf.eval(soa(wi), soa(wo), keys)
    assert isinstance(f_s, tuple) and len(f_s) == 3 and f_s[0].shape == (33,)
    np.testing.assert_array_equal(f_a, aos(f_s))
    np.testing.assert_array_equal(s_a, aos(s_s))
    # Mixed layouts: the result follows wi.
    np.testing.assert_array_equal(f_a, bsdf.eval(wi, soa(wo), keys)[0])
    for k in (None, keys):
        a = bsdf.sample(wi, k)
        s = bsdf.sample(soa(wi), k)
        np.testing.assert_array_equal(a[0], aos(s[0]))
        np.testing.assert_array_equal(a[1], aos(s[1]))
        np.testing.assert_array_equal(a[2], s[2])
        np.testing.assert_array_equal(a[3], s[3])
    np.testing.assert_array_equal(bsdf.pdf(wi, wo), bsdf.pdf(soa(wi), soa(wo)))
    ra = bsdf.albedo(wi, 64)
    rs = bsdf.albedo(soa(wi), 64)
    for x, y in zip(ra, rs):
        np.testing.assert_array_equal(x, aos(y))


def test_keys_select_streams(materials):
    bsdf = Bsdf.from_path(materials / "coated_copper.toml", samples=4)
    wi = np.tile(np.float32([0.0, 0.6, 0.8]), (4, 1))
    wo = np.tile(np.float32([0.6, 0.0, 0.8]), (4, 1))
    f, _ = bsdf.eval(wi, wo)  # keyed by the directions: four equal answers
    assert np.all(f == f[0])
    f, _ = bsdf.eval(wi, wo, np.array([1, 2, 1, 3], np.uint64))
    assert np.array_equal(f[0], f[2]) and not np.array_equal(f[0], f[1])
    s1 = bsdf.sample(wi, np.array([5, 6, 5, 7], np.uint64))[0]
    assert np.array_equal(s1[0], s1[2]) and not np.array_equal(s1[0], s1[1])


def test_lambertian_values():
    """A Lambertian alone: f = albedo / pi exactly (first order), R = albedo."""
    bsdf = Bsdf.from_toml(LAMBERT, samples=1)
    rng = np.random.default_rng(1)
    wi, wo = fixed_directions(50, rng), fixed_directions(50, rng)
    f, se = bsdf.eval(wi, wo)
    np.testing.assert_allclose(f, 0.7 / np.pi, rtol=1e-6)
    r, t, rse, tse = bsdf.albedo(wi[:3], 20000)
    assert np.all(np.abs(r - 0.7) < 5 * rse + 1e-6)
    assert np.all(t == 0)
    assert bsdf.lobes == {"delta_reflection": False, "delta_transmission": False, "glossy": False,
                          "diffuse": True, "transmission": False}


def test_transport_modes_differ_by_eta_squared():
    rad = Bsdf.from_toml(GLASS, samples=4, seed=1)
    imp = rad.with_transport("importance")
    assert (rad.transport, imp.transport) == ("radiance", "importance")
    wi = np.array([[0.3, 0.1, 0.9], [0.2, 0.0, -0.9], [0.1, 0.2, 0.9]], np.float32)
    wo = np.array([[-0.2, 0.0, -0.9], [-0.3, 0.1, 0.9], [0.0, -0.1, 0.95]], np.float32)
    keys = np.arange(3, dtype=np.uint64)
    fr, _ = rad.eval(wi, wo, keys)
    fi, _ = imp.eval(wi, wo, keys)
    # f*(wi -> wo) = f(wi -> wo) (n_i / n_o)^2: 1/2.25 entering, 2.25 leaving, 1 in reflection.
    np.testing.assert_allclose(fi[0], fr[0] / 2.25, rtol=1e-6)
    np.testing.assert_allclose(fi[1], fr[1] * 2.25, rtol=1e-6)
    np.testing.assert_array_equal(fi[2], fr[2])
    assert rad.exterior_ior == 1.0 and rad.exterior_ior_below == 1.5 and rad.transmissive


def test_gil_released_during_a_batch(materials):
    bsdf = Bsdf.from_path(materials / "thick_scattering.toml", samples=20000)
    wi = np.tile(np.float32([0, 0, 1]), (64, 1))
    ticks = []
    done = threading.Event()

    def spin():
        while not done.is_set():
            ticks.append(time.perf_counter())
            time.sleep(0.001)

    t = threading.Thread(target=spin)
    t.start()
    t0 = time.perf_counter()
    bsdf.eval(wi, wi)
    t1 = time.perf_counter()
    done.set()
    t.join()
    during = [x for x in ticks if t0 < x < t1]
    assert t1 - t0 > 0.05, "the batch is too short to tell"
    # The other thread kept running while the batch ran (with the GIL held, it could not).
    assert len(during) >= 10, (len(during), t1 - t0)


# The BSDF and queries of test_a_forked_child_runs_the_parents_batch, which its
# forked children inherit (as a renderer's forked workers would).
_FORKED = {}


def _forked_batch(_):
    """The batch of the test below: eval, sample and pdf (run in a child)."""
    b, wi, wo = _FORKED["bsdf"], _FORKED["wi"], _FORKED["wo"]
    f, se = b.eval(wi, wo)
    return f, se, b.sample(wi), b.pdf(wi, wo)


def test_a_forked_child_runs_the_parents_batch(materials):
    # Issue 39: after a batch on the thread pool, the same batch in a forked
    # child (multiprocessing's default start method on Linux) never returned:
    # the child's pool had no threads. Now it returns the parent's numbers.
    import multiprocessing

    rng = np.random.default_rng(39)
    n = 4096
    wi, wo = rng.normal(size=(2, n, 3)).astype(np.float32)
    wi[:, 2] = np.abs(wi[:, 2]) + 0.05
    wo[:, 2] = np.abs(wo[:, 2]) + 0.05
    _FORKED.update(bsdf=Bsdf.from_path(materials / "coated_copper.toml", samples=64, seed=7), wi=wi, wo=wo)
    try:
        parent = _forked_batch(0)
        with multiprocessing.get_context("fork").Pool(2) as pool:
            # Bounded: a child that waits on the parent's pool fails, not hangs.
            children = pool.map_async(_forked_batch, range(2)).get(timeout=60)
    finally:
        _FORKED.clear()

    def flat(r):
        return [np.asarray(x) for x in (r[0], r[1], *r[2], r[3])]

    for child in children:
        for want, got in zip(flat(parent), flat(child)):
            np.testing.assert_array_equal(got, want)


# ----------------------------------------------------------------------- errors


def bsdf():
    return Bsdf.from_toml(LAMBERT)


GOOD = np.array([[0, 0, 1], [0.6, 0, 0.8], [0, 0.6, 0.8]], np.float32)


@pytest.mark.parametrize(
    "wi,exc,words",
    [
        (np.zeros((3, 3)), TypeError, ["wi", "float32", "float64", "(3, 3)"]),
        (np.zeros((3, 4), np.float32), ValueError, ["wi", "(N, 3)", "(3, 4)"]),
        (np.zeros(3, np.float32), ValueError, ["wi", "(N, 3)", "(3,)"]),
        (np.zeros(0, np.float32), ValueError, ["wi", "(N, 3)", "(0,)"]),
        (np.zeros((3, 6), np.float32)[:, ::2], ValueError, ["wi", "C-contiguous", "(3, 3)"]),
        (np.frombuffer(bytearray(37), dtype=np.float32, offset=1, count=9).reshape(3, 3), ValueError,
         ["wi", "aligned", "(3, 3)"]),
        ([[0, 0, 1]] * 3, TypeError, ["wi", "(N, 3)", "got a list", "np.asarray"]),
        # Three rows in a list look like three columns: refused, not transposed.
        (list(GOOD), TypeError, ["wi", "got a list", "tuple(wi)"]),
        ((np.zeros(3, np.float32), [0, 0, 1], np.zeros(3, np.float32)), TypeError, ["wi.y", "float32", "list"]),
        ("up", TypeError, ["wi", "(N, 3)", "str"]),
        ((np.zeros(3, np.float32), np.zeros(3, np.float32)), ValueError, ["wi", "2 items"]),
        ((np.zeros(3, np.float32), np.zeros(3, np.float32), np.zeros(2, np.float32)), ValueError,
         ["wi.x, wi.y and wi.z", "3, 3 and 2"]),
        ((np.zeros(3, np.float32), np.zeros(3), np.zeros(3, np.float32)), TypeError, ["wi.y", "float64"]),
    ],
)
def test_bad_arrays_name_the_argument_and_shape(wi, exc, words):
    with pytest.raises(exc) as e:
        bsdf().eval(wi, GOOD)
    for w in words:
        assert w in str(e.value), (w, str(e.value))


def test_bad_directions_name_index_and_field():
    wo = GOOD.copy()
    wo[2] = 0
    with pytest.raises(QueryError) as e:
        bsdf().eval(GOOD, wo)
    assert str(e.value) == "query 2: wo = [0, 0, 0] is not a direction: it has zero length"
    assert e.value.index == 2 and isinstance(e.value, ValueError)
    wi = GOOD.copy()
    wi[1, 0] = np.nan
    for call in (lambda b: b.eval(wi, GOOD), lambda b: b.pdf(wi, GOOD), lambda b: b.sample(wi),
                 lambda b: b.albedo(wi, 4), lambda b: b.eval(soa(wi), soa(GOOD))):
        with pytest.raises(QueryError) as e:
            call(bsdf())
        assert str(e.value) == "query 1: wi = [NaN, 0, 0.8] is not a direction: components must be finite"
        assert e.value.index == 1
    wi[1, 0] = np.inf
    with pytest.raises(QueryError, match=r"query 1: wi = \[inf, 0, 0.8\]"):
        bsdf().sample(wi)


def test_bad_keys_and_counts():
    with pytest.raises(QueryError) as e:
        bsdf().eval(GOOD, GOOD, np.arange(2, dtype=np.uint64))
    assert "keys has 2 entries for 3 queries" in str(e.value) and e.value.index is None
    with pytest.raises(TypeError, match="keys must be None or a uint64 numpy array of shape \\(N,\\); got list"):
        bsdf().eval(GOOD, GOOD, [1, 2, 3])
    with pytest.raises(TypeError, match="keys must have dtype uint64; got int64"):
        bsdf().sample(GOOD, np.arange(3))
    with pytest.raises(ValueError, match="wo has 2 entries for 3 queries"):
        bsdf().eval(GOOD, GOOD[:2])
    with pytest.raises(QueryError, match="n = 0: at least one walk"):
        bsdf().albedo(GOOD, 0)
    with pytest.raises(ValueError, match="samples = 0"):
        Bsdf.from_toml(LAMBERT, samples=0)
    # Negative and huge integers are named with their value, as 0 is, not
    # left to a bare OverflowError.
    for bad in (-3, 2**64, 2**40 + 1):
        with pytest.raises(ValueError, match=f"^samples = {bad}: "):
            Bsdf.from_toml(LAMBERT, samples=bad)
        with pytest.raises(QueryError, match=f"^n = {bad}: ") as e:
            bsdf().albedo(GOOD, bad)
        assert e.value.index is None
        with pytest.raises(QueryError, match=f"^samples = {bad}: "):
            bsdf().pdf_unbiased(GOOD, GOOD, bad)
    for bad in (-1, 2**64):
        with pytest.raises(ValueError, match=f"^seed = {bad}: expected 0 to 2\\^64 − 1$"):
            Bsdf.from_toml(LAMBERT, seed=bad)
    assert Bsdf.from_toml(LAMBERT, seed=2**64 - 1).seed == 2**64 - 1
    # A count that is not a whole number is named with its value and type
    # (pyo3 adds a note, "while processing 'samples'").
    with pytest.raises(TypeError, match=r"^samples = 1\.5: expected a whole number, got float"):
        Bsdf.from_toml(LAMBERT, samples=1.5)
    with pytest.raises(TypeError, match=r"^seed = '7': expected a whole number, got str"):
        Bsdf.from_toml(LAMBERT, seed="7")
    with pytest.raises(TypeError, match=r"^n = 2\.5: expected a whole number, got float"):
        bsdf().albedo(GOOD, 2.5)
    with pytest.raises(ValueError, match=f"^seed = {2**130}: out of range"):
        Bsdf.from_toml(LAMBERT, seed=2**130)
    with pytest.raises(TypeError, match=r"^samples = None: expected a whole number, got NoneType"):
        bsdf().pdf_unbiased(GOOD, GOOD, None)
    with pytest.raises(TypeError, match=r"^pdf_samples = 1\.5: expected None .*, got float"):
        Bsdf.from_toml(LAMBERT, pdf_samples=1.5)
    with pytest.raises(ValueError, match="unknown transport mode"):
        Bsdf.from_toml(LAMBERT, transport="light")


def test_empty_batches_give_empty_results():
    e = np.zeros((0, 3), np.float32)
    f, se = bsdf().eval(e, e)
    assert f.shape == (0, 3) and se.shape == (0, 3) and f.dtype == np.float32
    wo, w, p, fl = bsdf().sample(e)
    assert wo.shape == (0, 3) and p.shape == (0,) and fl.dtype == np.uint32
    z = np.zeros(0, np.float32)
    f, _ = bsdf().eval((z, z, z), (z, z, z))
    assert all(c.shape == (0,) for c in f)


def test_material_errors_name_layer_and_field(tmp_path):
    with pytest.raises(MaterialError) as e:
        Bsdf.from_toml('[[layers]]\ninterface = { kind = "dielectric", ior = 1.5 \n')
    assert "invalid TOML material" in str(e.value) and "line 2" in str(e.value)
    assert isinstance(e.value, ValueError)
    thick = (
        '[[layers]]\ninterface = { kind = "dielectric", ior = 1.5 }\n'
        "medium = { thickness = -1.0, sigma_t = 1.0 }\n"
        '[[layers]]\ninterface = { kind = "diffuse", albedo = 0.5 }\n'
    )
    with pytest.raises(MaterialError) as e:
        Bsdf.from_toml(thick)
    assert str(e.value).startswith("invalid material: layer 0: medium.thickness = -1"), str(e.value)
    with pytest.raises(MaterialError, match="roughness"):
        Bsdf.from_toml('[[layers]]\ninterface = { kind = "dielectric", ior = 1.5, roughness = -0.1 }\n')
    with pytest.raises(MaterialError, match="invalid JSON material"):
        Bsdf.from_json("{")
    with pytest.raises(MaterialError, match="cannot read"):
        Bsdf.from_path(tmp_path / "missing.toml")
    p = tmp_path / "m.json"
    p.write_text(json.dumps({"layers": [{"interface": {"kind": "diffuse", "albedo": 0.5}}]}))
    assert Bsdf.from_path(p).interfaces == 1


@pytest.mark.parametrize("estimator", ["auto", "uni"])
def test_closed_form_stacks_sample_with_an_exact_pdf(materials, estimator):
    bsdf = Bsdf.from_path(materials / "clear_coat_lambertian.toml", seed=5, estimator=estimator)
    assert bsdf.exact_sampling == (estimator == "auto")
    rng = np.random.default_rng(8)
    wi = fixed_directions(16, rng)
    wo, weight, pdf, flags = bsdf.sample(wi)
    # Absorbed walks (flags 0, the walks' sampler only) have no direction.
    ok = flags != 0
    assert np.all(ok) or estimator == "uni"
    wi, wo, weight, pdf = wi[ok], wo[ok], weight[ok], pdf[ok]
    np.testing.assert_array_equal(pdf, bsdf.pdf(wi, wo))
    p, se = bsdf.pdf_unbiased(wi, wo, 64)
    if estimator == "auto":
        # The density itself: no walks, no standard error.
        np.testing.assert_array_equal(p, pdf)
        assert np.all(se == 0)
    else:
        assert np.any(se > 0)
    assert np.all(np.isfinite(weight)) and np.all(weight >= 0)



ROUGH_COAT = """
[[layers]]
interface = { kind = "dielectric", ior = 1.5, roughness = 0.2 }
medium = { thickness = 0.1, sigma_t = 1.0, albedo = 0.0 }
[[layers]]
interface = { kind = "diffuse", albedo = 0.6 }
"""


@pytest.mark.parametrize("estimator", ["auto", "uni"])
def test_a_rough_coat_over_lambertian_evaluates_without_walks(strata_cli, tmp_path, estimator):
    # The factorization under `auto` (estimator::rough_coat): sampled, not
    # exact, and bit for bit what the CLI prints for the same queries.
    path = tmp_path / "rough_coat.toml"
    path.write_text(ROUGH_COAT)
    bsdf = Bsdf.from_path(path, samples=256, seed=3, estimator=estimator)
    assert bsdf.eval_without_walks == (estimator == "auto")
    assert bsdf.exact_sampling == (estimator == "auto")
    rng = np.random.default_rng(4)
    wi = fixed_directions(8, rng)
    wo = fixed_directions(8, rng)
    f, se = bsdf.eval(wi, wo)
    assert np.all(np.isfinite(f)) and np.all(f > 0)
    assert np.all(se > 0)
    lines = query_lines(wi, wo)
    args = ["eval", "--material", str(path), "--samples", "256", "--seed", "3", "--estimator", estimator]
    cli = run_cli(strata_cli, args, lines)
    np.testing.assert_array_equal(f, np.array([c["f"] for c in cli], dtype=np.float64).astype(np.float32))
    np.testing.assert_array_equal(se, np.array([c["stderr"] for c in cli], dtype=np.float64).astype(np.float32))


def test_pdf_samples_beyond_128_bits_is_a_value_error():
    # A count pyo3 cannot hold as i128 is a ValueError naming it, as for
    # `samples` (it was a TypeError, as if it were not an int).
    for bad in (2**200, -(2**200)):
        with pytest.raises(ValueError, match=f"pdf_samples = {bad}: out of range"):
            Bsdf.from_toml(LAMBERT, pdf_samples=bad)


def run_isolated(code):
    """Runs `code` in a fresh interpreter (an allocation failure there aborts
    that process, not the tests): its exit status and output."""
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    return p.returncode, p.stdout + p.stderr


@pytest.mark.skipif(sys.platform != "linux", reason="sparse files and memory maps as on Linux")
def test_inputs_are_checked_before_results_are_allocated(tmp_path):
    # (2**32, 3) float32 directions, 48 GiB mapped from a sparse file that
    # costs no disk: a bad argument is a QueryError (a ValueError) before
    # anything is allocated for the results (it aborted the interpreter,
    # allocating them first).
    code = f"""
import numpy as np, strata_bsdf as sb
n = 2**32
def mapped(name):
    path = {str(tmp_path)!r} + "/" + name
    with open(path, "wb") as f:
        f.truncate(n * 3 * 4)
    return np.memmap(path, dtype=np.float32, mode="r+", shape=(n, 3))
wi, nan = mapped("wi"), mapped("nan")
wi[0] = (0, 0, 1)
nan[0] = (np.nan, 0, 1)
b = sb.Bsdf.from_toml({LAMBERT!r})
small = np.zeros((5, 3), np.float32)
calls = [
    ("eval short wo", lambda: b.eval(wi, small)),
    ("eval NaN wo", lambda: b.eval(wi, nan)),
    ("pdf NaN wi", lambda: b.pdf(nan, wi)),
    ("pdf_unbiased short wo", lambda: b.pdf_unbiased(wi, small, 4)),
    ("sample NaN wi", lambda: b.sample(nan)),
    ("sample short keys", lambda: b.sample(wi[:1], np.zeros(3, np.uint64))),
    ("albedo NaN wi", lambda: b.albedo(nan, 4)),
]
for name, call in calls:
    try:
        call()
        print(name, "answered")
    except ValueError as e:
        print(name, type(e).__name__, getattr(e, "index", "-"), e)
"""
    status, out = run_isolated(code)
    assert status == 0, out
    lines = out.splitlines()
    assert len(lines) == 7, out
    for line in lines:
        assert " QueryError " in line, out
    assert "eval short wo QueryError None" in out and "wo" in lines[0], out
    for i in (1, 2, 4, 6):
        assert "QueryError 0 query 0:" in lines[i] and "NaN" in lines[i], out
    assert "keys" in lines[5], out


@pytest.mark.skipif(sys.platform != "linux", reason="address-space limits as on Linux")
def test_results_too_large_to_allocate_are_a_memory_error():
    # Valid inputs whose results the process cannot allocate (its address
    # space limited to a little more than it uses): a MemoryError naming the
    # call, not an abort of the interpreter.
    code = f"""
import resource, numpy as np, strata_bsdf as sb
b = sb.Bsdf.from_toml({LAMBERT!r})
n = 1 << 22
wi = np.zeros((n, 3), np.float32)
wi[:, 2] = 1
size = [l for l in open("/proc/self/status") if l.startswith("VmSize:")][0]
used = int(size.split()[1]) * 1024
soft, hard = resource.getrlimit(resource.RLIMIT_AS)
resource.setrlimit(resource.RLIMIT_AS, (used + (16 << 20), hard))
for name, call in [("eval", lambda: b.eval(wi, wi)), ("sample", lambda: b.sample(wi)),
                   ("albedo", lambda: b.albedo(wi, 1))]:
    try:
        call()
        print(name, "answered")
    except MemoryError as e:
        print(name, "MemoryError", e)
"""
    status, out = run_isolated(code)
    assert status == 0, out
    for name in ("eval", "sample", "albedo"):
        assert f"{name} MemoryError Bsdf.{name}: cannot allocate its results" in out, out


def test_max_events_sets_the_walks_limit(materials):
    # max_events is the Rust API's limit of events per walk: it reads back,
    # survives the with_* copies, and at 3 events a scattering slab reflects
    # less than under the default (2**20); a limit outside 1..2**24 is a
    # ValueError naming it.
    path = materials / "scattering_slab.toml"
    wi = np.array([[0.3, 0.0, 0.95], [0.0, 0.6, 0.8]], dtype=np.float32)
    full = Bsdf.from_path(path, seed=3)
    three = Bsdf.from_path(path, seed=3, max_events=3)
    assert full.max_events == 2**20 and three.max_events == 3
    assert three.with_transport("importance").with_estimator("uni").max_events == 3
    r_full, _, se_full, _ = full.albedo(wi, 20000)
    r_three, _, se_three, _ = three.albedo(wi, 20000)
    z = (r_full - r_three) / np.hypot(se_full, se_three)
    assert np.all(z > 5), z
    for bad in (0, -1, 2**24 + 1, 2**200):
        with pytest.raises(ValueError, match=f"max_events = {bad}"):
            Bsdf.from_path(path, max_events=bad)
    with pytest.raises(TypeError, match="max_events = 1.5"):
        Bsdf.from_path(path, max_events=1.5)


@pytest.mark.parametrize(
    "material,pdf_samples,max_events",
    [("coated_copper.toml", None, None), ("scattering_slab.toml", "adaptive", None),
     ("scattering_slab.toml", None, 3), ("three_interfaces.toml", 4, None)],
)
def test_eval_pdf_is_eval_then_pdf_bit_for_bit(materials, material, pdf_samples, max_events):
    # eval_pdf (one library call) returns (f, stderr, pdf): bit for bit eval's
    # (f, stderr) and pdf's numbers, in both layouts, keyed or not, under the
    # lobe pdf and walked ones; its truncated count is eval's.
    rng = np.random.default_rng(11)
    extra = {} if max_events is None else {"max_events": max_events}
    bsdf = Bsdf.from_path(materials / material, samples=8, seed=4, pdf_samples=pdf_samples, **extra)
    wi = fixed_directions(29, rng, 0.3)
    wo = fixed_directions(29, rng, 0.3)
    keys = rng.integers(0, 2**63, size=29, dtype=np.uint64)
    want_pdf = bsdf.pdf(wi, wo)
    assert np.any(want_pdf > 0)
    for k in (None, keys):
        (f, se), cut = bsdf.eval(wi, wo, k, return_truncated=True)
        got = bsdf.eval_pdf(wi, wo, k)
        assert len(got) == 3 and got[2].dtype == np.float32 and got[2].shape == (29,)
        np.testing.assert_array_equal(got[0], f)
        np.testing.assert_array_equal(got[1], se)
        np.testing.assert_array_equal(got[2], want_pdf)
        assert [g.view(np.uint32).tolist() for g in got] == [
            x.view(np.uint32).tolist() for x in (f, se, want_pdf)]
        (f2, se2, p2), cut2 = bsdf.eval_pdf(wi, wo, k, return_truncated=True)
        assert cut2 == cut and (cut > 0) == (max_events is not None)
        np.testing.assert_array_equal(f2, f)
        np.testing.assert_array_equal(p2, want_pdf)
        fs, ses, ps = bsdf.eval_pdf(soa(wi), soa(wo), k)
        assert isinstance(fs, tuple) and len(fs) == 3
        np.testing.assert_array_equal(aos(fs), f)
        np.testing.assert_array_equal(aos(ses), se)
        np.testing.assert_array_equal(ps, want_pdf)


def test_eval_pdf_errors_name_the_argument():
    b = bsdf()
    with pytest.raises(ValueError) as e:
        b.eval_pdf(GOOD, np.zeros((3, 4), np.float32))
    assert "wo must have shape (N, 3); got shape (3, 4)" in str(e.value)
    with pytest.raises(TypeError, match="wi must have dtype float32; got float64"):
        b.eval_pdf(np.zeros((3, 3)), GOOD)
    with pytest.raises(ValueError, match="wo has 2 entries for 3 queries"):
        b.eval_pdf(GOOD, GOOD[:2])
    with pytest.raises(QueryError) as e:
        b.eval_pdf(GOOD, GOOD, np.arange(2, dtype=np.uint64))
    assert "keys has 2 entries for 3 queries" in str(e.value) and e.value.index is None
    with pytest.raises(TypeError, match="keys must have dtype uint64; got int64"):
        b.eval_pdf(GOOD, GOOD, np.arange(3))
    wi = GOOD.copy()
    wi[1, 0] = np.nan
    for w in (wi, soa(wi)):
        with pytest.raises(QueryError) as e:
            b.eval_pdf(w, GOOD)
        assert str(e.value) == "query 1: wi = [NaN, 0, 0.8] is not a direction: components must be finite"
        assert e.value.index == 1
    e3 = np.zeros((0, 3), np.float32)
    f, se, p = b.eval_pdf(e3, e3)
    assert f.shape == (0, 3) and se.shape == (0, 3) and p.shape == (0,) and p.dtype == np.float32


CONFIG_KEYS = ["samples", "pdf_walks", "seed", "transport", "eval_start", "estimator", "engine", "threads",
               "max_events", "rr_start", "rr_threshold", "max_scatter_order", "mis"]


def test_configure_reads_back_what_config_prints(materials):
    # config prints every setting as key=value pairs in a fixed order;
    # configure returns a new Bsdf with the pairs given (the rest kept) and
    # reads back what config prints.
    b = Bsdf.from_path(materials / "coated_copper.toml", samples=16, seed=5)
    text = b.config
    assert [p.split("=")[0] for p in text.split()] == CONFIG_KEYS
    assert text.startswith("samples=16 pdf_walks=lobes seed=5 transport=radiance ")
    settings = ("samples=3 pdf_walks=adaptive seed=7 transport=importance eval_start=wi estimator=uni "
                "engine=scalar threads=1 max_events=50 rr_start=2 rr_threshold=0.25 max_scatter_order=4 mis=false")
    c = b.configure(settings)
    assert isinstance(c, Bsdf) and c is not b
    assert c.config == settings
    assert b.config == text, "configure leaves the Bsdf it is called on as it was"
    assert (c.samples, c.seed, c.transport, c.estimator, c.max_events, c.pdf_samples) == (
        3, 7, "importance", "uni", 50, "adaptive")
    d = b.configure("  seed=8\n\tthreads=current ")
    assert d.config == text.replace("seed=5", "seed=8")
    again = Bsdf.from_path(materials / "coated_copper.toml").configure(c.config)
    assert again.configure("").config == c.config
    wi = fixed_directions(9, np.random.default_rng(2), 0.3)
    wo = fixed_directions(9, np.random.default_rng(3), 0.3)
    assert again.eval(wi, wo)[0].view(np.uint32).tolist() == c.eval(wi, wo)[0].view(np.uint32).tolist()


def bits_of(*arrays):
    return [np.ascontiguousarray(a).view(np.uint32).tolist() for a in arrays]


@pytest.mark.parametrize("material", ["scattering_slab.toml", "coated_copper.toml", "glass"])
def test_configure_answers_what_the_keyword_arguments_and_with_calls_make(materials, material):
    # Each setting by configure against the same one by from_path's keyword
    # arguments and the with_* copies: the same answers bit for bit.
    def load(**kw):
        if material == "glass":
            return Bsdf.from_toml(GLASS, **kw)
        return Bsdf.from_path(materials / material, **kw)

    rng = np.random.default_rng(17)
    wi = fixed_directions(21, rng, 0.3)
    wo = fixed_directions(21, rng, 0.3)

    def answers(b):
        f, se = b.eval(wi, wo)
        wo_s, weight, pdf_s, flags = b.sample(wi)
        return bits_of(f, se, b.pdf(wi, wo), wo_s, weight, pdf_s) + [flags.tolist()]

    plain = answers(load(samples=8, seed=3))
    for kw, settings in [
        (dict(transport="importance", estimator="uni", max_events=40, pdf_samples=4),
         "transport=importance estimator=uni max_events=40 pdf_walks=4"),
        (dict(estimator="bidir", pdf_samples=(8, 64, 0.15)), "estimator=bidir pdf_walks=8,64,0.15"),
        (dict(pdf_samples="tight", transport="radiance"), "pdf_walks=tight transport=radiance"),
    ]:
        by_kwargs = load(samples=8, seed=3, **kw)
        configured = load(samples=8, seed=3).configure(settings)
        assert configured.config == by_kwargs.config, settings
        got = answers(configured)
        assert got == answers(by_kwargs), settings
        if settings.startswith("transport=importance"):
            assert got != plain
    chained = load(samples=8, seed=3).with_transport("importance").with_estimator("uni")
    configured = load().configure("samples=8 seed=3 transport=importance estimator=uni")
    assert answers(configured) == answers(chained)


def test_a_setting_configure_does_not_take_is_a_value_error_naming_key_and_value():
    b = Bsdf.from_toml(GLASS, samples=4, seed=2).configure("transport=importance max_events=99")
    text = b.config
    for settings, message in [
        ("rr_threshold=2", "rr_threshold=2: expected a number from 0.001 to 1"),
        ("seed=9 samples=0", "samples=0: expected a whole number from 1 to 1099511627776"),
        ("colour=red", "colour=red: unknown setting (known: samples, pdf_walks, "),
        ("estimator=best", "estimator=best: "),
        ("threads=0", "threads=0: "),
        ("pdf_walks=1,2", "pdf_walks=1,2: "),
        ("seed=1 mis", "mis=: expected key=value"),
    ]:
        with pytest.raises(ValueError) as e:
            b.configure(settings)
        assert str(e.value).startswith(message), (settings, str(e.value))
        assert b.config == text
    with pytest.raises(TypeError):
        b.configure(3)
    with pytest.raises(AttributeError):
        b.config = "seed=1"
