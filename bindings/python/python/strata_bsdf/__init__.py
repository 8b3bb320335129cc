"""strata: layered BSDFs by position-free Monte Carlo (Guo, Hašan, Zhao 2018).

The compiled module answers batches of BSDF queries given as numpy arrays::

    import numpy as np
    import strata_bsdf

    bsdf = strata_bsdf.Bsdf.from_path("examples/materials/coated_copper.toml", samples=64)
    wi = np.array([[0.0, 0.0, 1.0], [0.6, 0.0, 0.8]], dtype=np.float32)
    wo = np.array([[0.0, 0.6, 0.8], [0.0, 0.0, 1.0]], dtype=np.float32)
    f, stderr = bsdf.eval(wi, wo)          # (2, 3) arrays: f without the cosine
    wo_s, weight, pdf, flags = bsdf.sample(wi)

Directions are float32 arrays of shape (N, 3), or tuples of three contiguous
float32 arrays of shape (N,) (the structure of arrays Dr.Jit hands out, read
without a copy); results have the layout of ``wi``. Each batch runs with the
GIL released. The numbers are bit for bit those of the Rust API and the
``strata`` CLI for the same seed and keys.

Every batch method takes ``params=``, per-query parameters: a dict from a
parameter path (``"layers[0].medium.thickness"``, docs/materials.md) to a
float32 array of shape (N,) or (N, 3); query k answers as the material with
row k's values::

    f, stderr = bsdf.eval(wi, wo, params={"layers[0].medium.thickness": np.float32([0.1, 2.0])})

``strata_bsdf.mitsuba`` is a Mitsuba 3 plugin (BSDF type ``"strata"``).
"""

from ._strata_bsdf import (
    DELTA,
    MAX_WALKS,
    REFLECTION,
    TRANSMISSION,
    Bsdf,
    MaterialError,
    QueryError,
    __version__,
)

__all__ = [
    "Bsdf",
    "QueryError",
    "MaterialError",
    "REFLECTION",
    "TRANSMISSION",
    "DELTA",
    "MAX_WALKS",
    "__version__",
]
