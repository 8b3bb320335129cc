"""Per-query parameters (`params=`): bit for bit the material with those values, and errors."""

import numpy as np
import pytest

from strata_bsdf import Bsdf, QueryError

from test_api import fixed_directions, soa

# A coat with a tinted, slightly scattering medium over a rough conductor:
# every kind of settable field (a dielectric's ior and roughness, a medium's
# thickness, sigma_t (RGB), albedo and phase.g, a conductor's eta and k (RGB)).
TEMPLATE = """
[[layers]]
interface = {{ kind = "dielectric", ior = {ior}, roughness = {rough} }}
medium = {{ thickness = {thickness}, sigma_t = {sigma_t}, albedo = {albedo}, phase = {{ kind = "hg", g = {g} }} }}
[[layers]]
interface = {{ kind = "conductor", eta = {eta}, k = [3.9, 2.45, 2.2], roughness = 0.25 }}
"""
BASE = dict(ior=1.5, rough=0.1, thickness=0.5, sigma_t=[0.2, 0.6, 1.2], albedo=0.3, g=0.2, eta=[0.2, 0.92, 1.1])


def decimal(x):
    """The number a float32 `x` of a params array sets, as text: the first of
    its correctly rounded decimals of 1 to 9 digits that reads back as `x`
    (`str(np.float32(x))` but at a few powers of two far outside any parameter
    range, where numpy's shortest digits are not the correctly rounded ones)."""
    x = np.float32(x)
    return next(s for s in ("%.*g" % (p, float(x)) for p in range(1, 10)) if np.float32(s) == x)


def toml(**values):
    """The material with `values`, each float as the number its float32 sets."""
    def text(v):
        if isinstance(v, (list, tuple, np.ndarray)):
            return "[" + ", ".join(decimal(x) for x in v) + "]"
        return decimal(v)
    return TEMPLATE.format(**{k: text(v) for k, v in dict(BASE, **values).items()})


N = 6
ROWS = {
    "layers[0].medium.thickness": ("thickness", np.float32([0.1, 0.5, 2.0, 0.5, 0.0, 1.3])),
    "layers[0].interface.roughness": ("rough", np.float32([0.1, 0.3, 0.05, 0.6, 0.2, 0.1])),
    "layers[0].medium.sigma_t": ("sigma_t", np.float32([[0.2, 0.6, 1.2], [1, 1, 1], [0, 0.1, 3],
                                                       [0.2, 0.6, 1.2], [5, 0.3, 0.3], [0.7, 0.7, 0.1]])),
    "layers[1].interface.eta": ("eta", np.float32([[0.2, 0.92, 1.1], [1.1, 0.9, 0.3], [0.2, 0.92, 1.1],
                                                  [0.5, 0.5, 0.5], [2, 1, 0.4], [0.3, 0.3, 0.9]])),
    "layers[0].medium.phase.g": ("g", np.float32([0.2, -0.5, 0.9, 0.0, 0.2, 0.4])),
}


def per_row(samples, seed, transport="radiance"):
    """The BSDF of each row's material."""
    out = []
    for k in range(N):
        vals = {field: col[k] for field, col in ROWS.values()}
        out.append(Bsdf.from_toml(toml(**vals), samples=samples, seed=seed, transport=transport))
    return out


def params():
    return {path: col for path, (_, col) in ROWS.items()}


def rows(a, k):
    return a[k : k + 1]


@pytest.mark.parametrize("transport", ["radiance", "importance"])
def test_params_bit_identical_to_the_materials(transport):
    rng = np.random.default_rng(5)
    samples, seed = 8, 77
    wi = fixed_directions(N, rng)
    wo = fixed_directions(N, rng)
    keys = rng.integers(0, 2**63, size=N, dtype=np.uint64)
    base = Bsdf.from_toml(toml(), samples=samples, seed=seed, transport=transport)
    ones = per_row(samples, seed, transport)
    p = params()

    for k_arg in (None, keys):
        f, se = base.eval(wi, wo, k_arg, params=p)
        for k, b in enumerate(ones):
            fk, sk = b.eval(rows(wi, k), rows(wo, k), None if k_arg is None else rows(keys, k))
            np.testing.assert_array_equal(f[k], fk[0])
            np.testing.assert_array_equal(se[k], sk[0])
        # Samples: unkeyed, query k draws sample index k of its direction's key;
        # a batch of identical rows with the one BSDF does the same.
        wo_s, w_s, p_s, fl_s = base.sample(wi, k_arg, params=p)
        for k, b in enumerate(ones):
            if k_arg is None:
                ref = b.sample(np.repeat(rows(wi, k), N, axis=0))
                ref = tuple(r[k : k + 1] for r in ref)
            else:
                ref = b.sample(rows(wi, k), rows(keys, k))
            for got, want in zip((wo_s, w_s, p_s, fl_s), ref):
                np.testing.assert_array_equal(got[k], want[0])
        r = base.albedo(wi, 16, k_arg, params=p)
        for k, b in enumerate(ones):
            ref = b.albedo(rows(wi, k), 16, None if k_arg is None else rows(keys, k))
            for got, want in zip(r, ref):
                np.testing.assert_array_equal(got[k], want[0])

    pdf = base.pdf(wi, wo, params=p)
    # eval_pdf: eval's and pdf's numbers in one call, per query too (rows
    # written in place, and rows that are materials: an IOR column).
    iors = {"layers[0].interface.ior": np.float32([1.3, 1.5, 1.45, 1.7, 1.33, 1.6])}
    for pp in (p, dict(p, **iors)):
        want_pdf = base.pdf(wi, wo, params=pp)
        for k_arg in (None, keys):
            fe, se_e = base.eval(wi, wo, k_arg, params=pp)
            got = base.eval_pdf(wi, wo, k_arg, params=pp)
            for g, w in zip(got, (fe, se_e, want_pdf)):
                np.testing.assert_array_equal(g, w)
            got = base.eval_pdf(soa(wi), soa(wo), k_arg, params=pp)
            np.testing.assert_array_equal(np.stack(got[0], axis=1), fe)
            np.testing.assert_array_equal(got[2], want_pdf)
    pu, pu_se = base.pdf_unbiased(wi, wo, 8, params=p)
    for k, b in enumerate(ones):
        np.testing.assert_array_equal(pdf[k], b.pdf(rows(wi, k), rows(wo, k))[0])
        u, u_se = b.pdf_unbiased(rows(wi, k), rows(wo, k), 8)
        assert (pu[k], pu_se[k]) == (u[0], u_se[0])
    # The parameters matter: not the base material's answers.
    assert not np.array_equal(f, base.eval(wi, wo, keys)[0])
    # Structure of arrays in, structure of arrays out, the same numbers.
    f_soa, _ = base.eval(soa(wi), soa(wo), keys, params=p)
    np.testing.assert_array_equal(np.stack(f_soa, axis=1), f)


def test_repeated_rows_and_width_one_rgb():
    """Rows that repeat (as a texture's do) answer as distinct ones; an RGB field
    also takes one number per query (grey), as a material file does."""
    base = Bsdf.from_toml(toml(), samples=4, seed=3)
    wi = np.tile(np.float32([0.0, 0.6, 0.8]), (4, 1))
    th = np.float32([0.25, 1.0, 0.25, 1.0])
    sig = np.float32([0.5, 0.5, 2.0, 2.0])
    f, _ = base.eval(wi, wi, np.arange(4, dtype=np.uint64),
                     params={"layers[0].medium.thickness": th, "layers[0].medium.sigma_t": sig})
    for k in range(4):
        b = Bsdf.from_toml(toml(thickness=th[k], sigma_t=sig[k]), samples=4, seed=3)
        np.testing.assert_array_equal(f[k], b.eval(wi[:1], wi[:1], np.uint64([k]))[0][0])
    # Empty params and no params: the BSDF itself.
    np.testing.assert_array_equal(base.eval(wi, wi, params={})[0], base.eval(wi, wi)[0])
    e = np.zeros((0, 3), np.float32)
    assert base.eval(e, e, params={"layers[0].medium.thickness": np.zeros(0, np.float32)})[0].shape == (0, 3)


GOOD = np.array([[0, 0, 1], [0.6, 0, 0.8], [0, 0.6, 0.8], [0.8, 0, 0.6]], np.float32)
TH = "layers[0].medium.thickness"


def call(method, p):
    b = Bsdf.from_toml(toml())
    return {
        "eval": lambda: b.eval(GOOD, GOOD, params=p),
        "eval_pdf": lambda: b.eval_pdf(GOOD, GOOD, params=p),
        "sample": lambda: b.sample(GOOD, params=p),
        "pdf": lambda: b.pdf(GOOD, GOOD, params=p),
        "pdf_unbiased": lambda: b.pdf_unbiased(GOOD, GOOD, 4, params=p),
        "albedo": lambda: b.albedo(GOOD, 4, params=p),
    }[method]()


METHODS = ["eval", "eval_pdf", "sample", "pdf", "pdf_unbiased", "albedo"]


@pytest.mark.parametrize("method", METHODS)
def test_invalid_value_names_query_path_and_value(method):
    th = np.float32([0.5, 0.5, 0.5, -1.0])
    with pytest.raises(QueryError) as e:
        call(method, {TH: th})
    msg = str(e.value)
    assert msg.startswith("query 3: set `layers[0].medium.thickness` = -1"), msg
    assert "invalid material" in msg and e.value.index == 3
    th[1] = np.nan  # the first bad query is reported
    with pytest.raises(QueryError) as e:
        call(method, {TH: th})
    assert str(e.value).startswith("query 1: set `layers[0].medium.thickness` = NaN"), str(e.value)
    assert e.value.index == 1


@pytest.mark.parametrize(
    "p,exc,words",
    [
        ({TH: np.zeros(3, np.float32)}, ValueError, ['params["layers[0].medium.thickness"]', "(4,) or (4, 3)", "(3,)"]),
        ({TH: np.zeros((4, 2), np.float32)}, ValueError, ["layers[0].medium.thickness", "(4, 2)"]),
        ({TH: np.zeros((4, 3, 1), np.float32)}, ValueError, ["layers[0].medium.thickness", "(4, 3, 1)"]),
        ({TH: np.zeros(4)}, TypeError, ["layers[0].medium.thickness", "float32", "float64", "(4,)"]),
        ({TH: [0.5] * 4}, TypeError, ["layers[0].medium.thickness", "list"]),
        ({TH: np.zeros(8, np.float32)[::2]}, ValueError, ["layers[0].medium.thickness", "C-contiguous"]),
        ({"layers[0].medium.thicknes": np.zeros(4, np.float32)}, ValueError,
         ["layers[0].medium.thicknes", "unknown medium field"]),
        ({"layers[0].interface.kind": np.zeros(4, np.float32)}, ValueError, ["kind", "not a numeric parameter"]),
        ({"layers[5].medium.thickness": np.ones(4, np.float32)}, ValueError, ["layers[5].medium.thickness", "no layer 5"]),
        ({"layers[1].interface.ior": np.ones(4, np.float32)}, ValueError, ["layers[1].interface.ior", "conductor"]),
        ({3: np.ones(4, np.float32)}, TypeError, ["params keys", "int"]),
        ([1, 2], TypeError, ["params must be None or a dict", "list"]),
    ],
)
def test_bad_params_name_the_path_and_shape(p, exc, words):
    for method in METHODS:
        with pytest.raises(exc) as e:
            call(method, p)
        for w in words:
            assert w in str(e.value), (method, w, str(e.value))


@pytest.mark.parametrize("method", METHODS)
def test_an_empty_batch_checks_its_params_against_the_material(method):
    b = Bsdf.from_toml(toml())
    e3, e1, e13 = np.zeros((0, 3), np.float32), np.zeros(0, np.float32), np.zeros((0, 3), np.float32)
    run = {
        "eval": lambda p: b.eval(e3, e3, params=p),
        "eval_pdf": lambda p: b.eval_pdf(e3, e3, params=p),
        "sample": lambda p: b.sample(e3, params=p),
        "pdf": lambda p: b.pdf(e3, e3, params=p),
        "pdf_unbiased": lambda p: b.pdf_unbiased(e3, e3, 4, params=p),
        "albedo": lambda p: b.albedo(e3, 4, params=p),
    }[method]
    with pytest.raises(ValueError, match=r"params: set `layers\[5\].medium.thickness`: there is no layer 5"):
        run({"layers[5].medium.thickness": e1})
    with pytest.raises(ValueError, match=r'params\["layers\[0\].medium.thickness"\] has shape \(0, 3\)'):
        run({TH: e13})
    out = run({TH: e1})  # good params, no queries: empty results
    first = out[0] if isinstance(out, tuple) else out
    assert len(first) == 0


@pytest.mark.parametrize("method", METHODS)
def test_triple_for_a_number_names_path_and_shape(method):
    with pytest.raises(ValueError) as e:
        call(method, {TH: np.ones((4, 3), np.float32)})
    msg = str(e.value)
    assert msg.startswith('params["layers[0].medium.thickness"] has shape (4, 3) (a triple per query)'), msg
    assert "[1.0,1.0,1.0]" in msg and not isinstance(e.value, QueryError), msg
    # A non-finite triple is the query's fault, named as such.
    v = np.ones((4, 3), np.float32)
    v[2, 1] = np.inf
    with pytest.raises(QueryError) as e:
        call(method, {"layers[0].medium.sigma_t": v})
    assert str(e.value).startswith("query 2: set `layers[0].medium.sigma_t` = inf"), str(e.value)


OOM_SNIPPET = r"""
import resource, sys
import numpy as np
from strata_bsdf import Bsdf

COATED_COPPER = '''
[[layers]]
interface = { kind = "dielectric", ior = 1.5, roughness = 0.1 }
medium = { thickness = 0.5, sigma_t = [0.2, 0.6, 1.2], albedo = 0.0 }
[[layers]]
interface = { kind = "conductor", preset = "Cu", roughness = 0.2 }
'''
n = 10**6
b = Bsdf.from_toml(COATED_COPPER, samples=1)
wi = np.tile(np.float32([0.0, 0.6, 0.8]), (n, 1))
th = (np.float32(0.05) + np.arange(n, dtype=np.float32) * np.float32(1e-6)).astype(np.float32)
p = {"layers[0].medium.thickness": th}
b.pdf(wi[:64], wi[:64], params={"layers[0].medium.thickness": th[:64]})  # threads, buffers
mapped = int(open("/proc/self/statm").read().split()[0]) * resource.getpagesize()
# Room for the results (n floats, a page more) and no more: the call's
# working memory (its chunk's buffers) is what is refused.
room = mapped + 4 * n + (64 << 10)
resource.setrlimit(resource.RLIMIT_AS, (room, room))
try:
    b.pdf(wi, wi, params=p)
except MemoryError as e:
    print("MemoryError:", e)
    sys.exit(0)
print("no MemoryError")
sys.exit(1)
"""


@pytest.mark.skipif(not __import__("sys").platform.startswith("linux"), reason="RLIMIT_AS, /proc")
def test_out_of_memory_is_a_memory_error():
    """A `params=` call that cannot have its working memory (under a lowered
    address-space limit) raises MemoryError naming the bytes, not an abort."""
    import subprocess
    import sys
    r = subprocess.run([sys.executable, "-c", OOM_SNIPPET], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, (r.returncode, r.stdout, r.stderr)
    assert "MemoryError:" in r.stdout and "out of memory" in r.stdout and "bytes" in r.stdout, r.stdout
