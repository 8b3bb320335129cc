"""Type stubs of the compiled module (re-exported by ``strata_bsdf``)."""

from os import PathLike
from typing import Dict, Literal, Optional, Tuple, TypedDict, Union, overload

import numpy as np
import numpy.typing as npt

F32 = npt.NDArray[np.float32]
#: Directions or RGB values: an (N, 3) float32 array, or three contiguous (N,) float32 arrays.
Vectors = Union[F32, Tuple[F32, F32, F32]]
Keys = Optional[npt.NDArray[np.uint64]]
Transport = Literal["radiance", "importance"]
Estimator = Literal["auto", "uni", "unidirectional", "bidir", "bidirectional"]
#: Per-query parameters: a parameter path of the material ("layers[0].medium.thickness",
#: "layers[0].medium.sigma_t", "exterior_ior"; docs/materials.md) to a C-contiguous float32
#: array of shape (N,) (a number per query) or (N, 3) (a triple per query).
Params = Optional[Dict[str, F32]]
#: Spectral queries: a C-contiguous float32 array of shape (N, 3), query k's three wavelengths
#: in nm; channel c of every result is then the value at wavelength c (docs/materials.md, *Spectra*).
Wavelengths = Optional[F32]
#: Density walks per approximate pdf: None or "default" (the library's rule), a fixed count,
#: "tight" (a pdf within 0.7-1.3x of sample's density nearly everywhere, about twice the
#: walks), or an adaptive rule (pilot, max, rel_stderr).
PdfSamples = Union[None, int, Literal["default", "lobes", "adaptive", "tight"], Tuple[int, int, float]]

REFLECTION: int
TRANSMISSION: int
DELTA: int
MAX_WALKS: int
__version__: str

class QueryError(ValueError):
    """A query that cannot be answered; ``index`` is its index in the batch
    (None for a fault in an argument of the whole call)."""

    index: Optional[int]

class MaterialError(ValueError):
    """A material that cannot be loaded (the message names layer, field and value)."""

class Lobes(TypedDict):
    delta_reflection: bool
    delta_transmission: bool
    glossy: bool
    diffuse: bool
    transmission: bool

class Bsdf:
    """A strata layered BSDF answering batches of queries (local frame, z = normal,
    both directions pointing away from the surface)."""

    @staticmethod
    def from_toml(
        text: str,
        samples: int = 1,
        seed: int = 0,
        transport: Transport = "radiance",
        pdf_samples: PdfSamples = None,
        estimator: Estimator = "auto",
        max_events: Optional[int] = None,
    ) -> Bsdf: ...
    @staticmethod
    def from_json(
        text: str,
        samples: int = 1,
        seed: int = 0,
        transport: Transport = "radiance",
        pdf_samples: PdfSamples = None,
        estimator: Estimator = "auto",
        max_events: Optional[int] = None,
    ) -> Bsdf: ...
    @staticmethod
    def from_path(
        path: Union[str, PathLike[str]],
        samples: int = 1,
        seed: int = 0,
        transport: Transport = "radiance",
        pdf_samples: PdfSamples = None,
        estimator: Estimator = "auto",
        max_events: Optional[int] = None,
    ) -> Bsdf: ...
    def with_transport(self, transport: Transport) -> Bsdf: ...
    def with_estimator(self, estimator: Estimator) -> Bsdf: ...
    def configure(self, settings: str) -> Bsdf:
        """A new Bsdf with `settings` ("key=value ..." pairs, the keys of
        `config`) applied; this one is unchanged. Raises ValueError naming the
        key and the value."""
    @property
    def config(self) -> str:
        """Every setting as "key=value" pairs in a fixed order: text that
        `configure` reads back."""
    @overload
    def eval(
        self,
        wi: Vectors,
        wo: Vectors,
        keys: Keys = None,
        *,
        params: Params = None,
        wavelengths: Wavelengths = None,
        return_truncated: Literal[False] = False,
    ) -> Tuple[Vectors, Vectors]:
        """(f, stderr): f(wi, wo) per channel without the cosine, and its standard error.

        params: query k answers as the material with row k of every array set
        (bit for bit, same seed and keys); an invalid row raises QueryError
        naming the query, the path and the value.

        wavelengths: channel c of query k answers at wavelength wavelengths[k, c]
        (a material whose IOR varies takes one wavelength three times a query;
        wavelengths_per_walk).

        return_truncated=True (eval, eval_pdf, pdf_unbiased, albedo): returns (result, truncated),
        truncated the number of walks the limit of events (max_events) ended in the
        call, summed over the batch; 0 when none did."""
    @overload
    def eval(
        self,
        wi: Vectors,
        wo: Vectors,
        keys: Keys = None,
        *,
        params: Params = None,
        wavelengths: Wavelengths = None,
        return_truncated: Literal[True],
    ) -> Tuple[Tuple[Vectors, Vectors], int]: ...
    @overload
    def eval_pdf(
        self,
        wi: Vectors,
        wo: Vectors,
        keys: Keys = None,
        *,
        params: Params = None,
        wavelengths: Wavelengths = None,
        return_truncated: Literal[False] = False,
    ) -> Tuple[Vectors, Vectors, F32]:
        """(f, stderr, pdf): eval and pdf of the same pairs in one call, bit for bit
        eval(wi, wo, keys) and pdf(wi, wo) (a light sample's value and its MIS density).
        return_truncated=True: ((f, stderr, pdf), truncated), as for eval."""
    @overload
    def eval_pdf(
        self,
        wi: Vectors,
        wo: Vectors,
        keys: Keys = None,
        *,
        params: Params = None,
        wavelengths: Wavelengths = None,
        return_truncated: Literal[True],
    ) -> Tuple[Tuple[Vectors, Vectors, F32], int]: ...
    def sample(
        self, wi: Vectors, keys: Keys = None, *, params: Params = None, wavelengths: Wavelengths = None
    ) -> Tuple[Vectors, Vectors, F32, npt.NDArray[np.uint32]]:
        """(wo, weight, pdf, flags): weight = f |cos θo| / p; flags REFLECTION | TRANSMISSION | DELTA, 0 if absorbed."""
    def pdf(self, wi: Vectors, wo: Vectors, *, params: Params = None, wavelengths: Wavelengths = None) -> F32:
        """The approximate density of sample's wo (what sample reports as pdf)."""
    @overload
    def pdf_unbiased(
        self,
        wi: Vectors,
        wo: Vectors,
        samples: int,
        *,
        params: Params = None,
        wavelengths: Wavelengths = None,
        return_truncated: Literal[False] = False,
    ) -> Tuple[F32, F32]:
        """(pdf, stderr): the density of sample's directions from `samples` density walks
        (slow). return_truncated=True: ((pdf, stderr), truncated), as for eval."""
    @overload
    def pdf_unbiased(
        self,
        wi: Vectors,
        wo: Vectors,
        samples: int,
        *,
        params: Params = None,
        wavelengths: Wavelengths = None,
        return_truncated: Literal[True],
    ) -> Tuple[Tuple[F32, F32], int]: ...
    @overload
    def albedo(
        self,
        wi: Vectors,
        n: int,
        keys: Keys = None,
        *,
        params: Params = None,
        wavelengths: Wavelengths = None,
        return_truncated: Literal[False] = False,
    ) -> Tuple[Vectors, Vectors, Vectors, Vectors]:
        """(R, T, R_stderr, T_stderr) from n walks per direction. return_truncated=True:
        ((R, T, R_stderr, T_stderr), truncated), as for eval (a walk counts once)."""
    @overload
    def albedo(
        self,
        wi: Vectors,
        n: int,
        keys: Keys = None,
        *,
        params: Params = None,
        wavelengths: Wavelengths = None,
        return_truncated: Literal[True],
    ) -> Tuple[Tuple[Vectors, Vectors, Vectors, Vectors], int]: ...
    @property
    def estimator(self) -> Estimator: ...
    @property
    def max_events(self) -> int:
        """The limit of events per walk."""
    @property
    def pdf_samples(self) -> PdfSamples:
        """How the approximate pdf is made, as pdf_samples takes it: None for the
        library's default (the lobe pdf), "adaptive", "tight", a fixed count of
        density walks, or (pilot, max, rel_stderr)."""
    @property
    def bidirectional(self) -> bool: ...
    @property
    def exact_sampling(self) -> bool: ...
    @property
    def eval_without_walks(self) -> bool: ...
    @property
    def samples(self) -> int: ...
    @property
    def seed(self) -> int: ...
    @property
    def transport(self) -> Transport: ...
    @property
    def description(self) -> Optional[str]: ...
    @property
    def interfaces(self) -> int: ...
    @property
    def transmissive(self) -> bool: ...
    @property
    def two_sided(self) -> bool: ...
    @property
    def exterior_ior(self) -> float: ...
    @property
    def exterior_ior_below(self) -> float: ...
    @property
    def lobes(self) -> Lobes: ...
    @property
    def wavelengths_per_walk(self) -> int:
        """3, or 1 where the IOR varies with wavelength (one walk refracts at one IOR)."""
