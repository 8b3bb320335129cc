"""The count of walks the limit of events ended (`return_truncated=True`).

On a lossless slab of optical depth 10^4 (crates/strata-bsdf/tests/data/
lossless_slab_tau_1e4.toml), every walk that leaves carries weight 1, so under a
small `max_events` the albedo's R + T of a batch is exactly the fraction of its
walks the limit did not end: the count is checked against that, and against
itself across layouts and per-query params; on an ordinary stack it is 0.
"""

import pathlib

import numpy as np
import pytest

from strata_bsdf import Bsdf

ROOT = pathlib.Path(__file__).resolve().parents[3]
LOSSLESS = ROOT / "crates" / "strata-bsdf" / "tests" / "data" / "lossless_slab_tau_1e4.toml"

WI = np.array(
    [[0.5, 0.0, 0.866], [0.0, 0.3, 0.95], [-0.6, 0.2, 0.77], [0.1, -0.1, 0.99]],
    dtype=np.float32,
)
WO = np.array(
    [[-0.3, 0.1, 0.95], [0.2, 0.0, -0.98], [0.5, 0.5, 0.7], [0.0, 0.6, -0.8]],
    dtype=np.float32,
)
KEYS = np.arange(1, 5, dtype=np.uint64)


def soa(v):
    return tuple(np.ascontiguousarray(v[:, c]) for c in range(3))


def slab(samples=256):
    return Bsdf.from_path(LOSSLESS, samples=samples, seed=5, max_events=64)


def test_albedo_counts_exactly_the_walks_the_limit_ended():
    n = 2000
    (r, t, r_se, t_se), cut = slab().albedo(WI, n, KEYS, return_truncated=True)
    assert isinstance(cut, int)
    m = len(WI)
    assert 0 < cut < m * n, cut
    kept = (r + t).astype(np.float64) * n  # per query and channel
    for c in range(3):
        assert abs(kept[:, c].sum() - (m * n - cut)) < 1e-5 * m * n, (kept[:, c].sum(), cut)
    # The result is the call's without the keyword, bit for bit.
    plain = slab().albedo(WI, n, KEYS)
    for a, b in zip((r, t, r_se, t_se), plain):
        assert np.array_equal(a, b)


def test_eval_and_pdf_unbiased_count_theirs_in_every_layout_and_with_params():
    b = slab()
    (f, se), cut = b.eval(WI, WO, KEYS, return_truncated=True)
    assert 0 < cut <= len(WI) * 256, cut
    f_plain, se_plain = b.eval(WI, WO, KEYS)
    assert np.array_equal(f, f_plain) and np.array_equal(se, se_plain)
    (f_soa, _), cut_soa = b.eval(soa(WI), soa(WO), KEYS, return_truncated=True)
    assert cut_soa == cut
    assert all(np.array_equal(f_soa[c], f[:, c]) for c in range(3))
    # A column of the material's own thickness: one material per query,
    # the same numbers and the same count.
    params = {"layers[0].medium.thickness": np.ones(len(WI), dtype=np.float32)}
    (f_p, _), cut_p = b.eval(WI, WO, KEYS, params=params, return_truncated=True)
    assert cut_p == cut and np.array_equal(f_p, f)

    (pdf, pdf_se), cut = b.pdf_unbiased(WI, WO, 128, return_truncated=True)
    assert 0 < cut, cut
    assert np.all(np.isfinite(pdf)) and np.all(pdf >= 0)
    _, cut_p = b.pdf_unbiased(WI, WO, 128, params=params, return_truncated=True)
    assert cut_p == cut


def test_an_ordinary_stack_counts_none(materials):
    b = Bsdf.from_path(materials / "coated_copper.toml", samples=64, seed=1)
    assert b.eval(WI, WO, return_truncated=True)[1] == 0
    assert b.pdf_unbiased(WI, WO, 64, return_truncated=True)[1] == 0
    assert b.albedo(WI, 500, return_truncated=True)[1] == 0
    # Without the keyword, the results alone.
    assert len(b.eval(WI, WO)) == 2 and len(b.albedo(WI, 16)) == 4


def test_return_truncated_is_keyword_only():
    with pytest.raises(TypeError):
        slab().eval(WI, WO, None, None, True)
