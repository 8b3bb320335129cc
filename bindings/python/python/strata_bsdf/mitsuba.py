"""A Mitsuba 3 plugin: strata's layered BSDFs as the BSDF type ``"strata"``.

Usage::

    import mitsuba as mi
    mi.set_variant("llvm_ad_rgb")        # or scalar_rgb, scalar_spectral, llvm_ad_spectral
    import strata_bsdf.mitsuba           # registers "strata" for this variant

    scene = mi.load_dict({
        ...,
        "shape": {"type": "sphere",
                  "bsdf": {"type": "strata",
                           "filename": "examples/materials/coated_copper.toml",
                           "samples": 1, "seed": 0}},
    })

Parameters of ``"strata"``:

* ``filename`` (string): a strata material, TOML or JSON (``.json``),
  resolved through Mitsuba's file resolver.
* ``samples`` (int, default 1): walks per ``eval`` (each eval is an unbiased
  estimate; more walks, less noise per call).
* ``seed`` (int, default 0): seeds strata's random streams.
* ``pdf_samples`` (int or string, default: the library's, the lobe pdf, a
  closed form with no walk): a fixed number of density walks per pdf (at
  least 1), ``"adaptive"`` (a pilot of 8 walks, then 8 to 64 for a relative
  standard error of 0.15) or ``"tight"`` (8, then 8 to 128 for 0.1: a pdf
  within 0.7–1.3× of the density of the samples at nearly every direction);
  docs/method.md §6 compares them.
* ``config`` (string): any of the library's settings as ``key=value`` text
  (``"estimator=bidir threads=1"``; ``Bsdf.configure``, docs/embedding.md),
  applied after the parameters above; a bad setting is a ``ValueError``
  naming the key and the value.
* ``param:<path>`` (float, RGB or texture, any number of them): a parameter
  of the material that varies over the surface, e.g.
  ``"param:layers[0]:medium:thickness": {"type": "bitmap", ...}``. The path
  is a strata parameter path (``layers[0].medium.thickness``,
  ``layers[0].medium.sigma_t``, ``layers[1].interface.roughness``,
  ``exterior_ior``; docs/materials.md) with ``:`` for ``.`` (Mitsuba
  reserves ``.`` in property names). The value is any Mitsuba texture
  (``bitmap``, ``checkerboard``, ...) or a constant, read unbounded (a
  ``sigma_t`` of 5 stays 5). At every hit the texture is evaluated at the
  surface interaction, with ``eval_1`` for a field that takes one number and
  ``eval`` (RGB) for a field that takes a triple, and the values go to
  strata as per-query parameters (``Bsdf.eval(..., params=...)``): the hit
  answers bit for bit what the material with those values answers. Which of
  the two a field takes is asked of strata when the BSDF is built (with the
  texture's mean, which must make a valid material); an invalid texel (a
  negative thickness) raises an error naming the query, path and value.
  A ``normal`` path (``param:layers[i]:interface:normal``) is a **normal
  map**: its RGB ``c`` is decoded as Mitsuba's ``normalmap`` decodes it,
  ``n = 2c - 1`` in the surface's local frame, and lanes not queried get the
  untilted ``[0, 0, 1]`` (method.md §9 says what a tilted interface does).

**Spectral variants** (``scalar_spectral``, ``llvm_ad_spectral``). Mitsuba
hands a BSDF four wavelengths per path, and the plugin answers at them
(``wavelengths=`` of :class:`Bsdf`; the material's spectra, presets and
dispersion laws are read there, its RGB values through strata's uplift).
strata's walks carry three wavelengths, or one where an IOR varies with
wavelength (``Bsdf.wavelengths_per_walk``). So ``eval`` makes two strata
calls per batch, the first three wavelengths and then the fourth (four calls,
one per wavelength, where the IOR varies), and its ``pdf`` is that of the
first call. ``sample`` walks once: it keeps the first call's wavelengths,
weighted by 4/3 (by 4 where the IOR varies), and gives the others 0. That
is unbiased because Mitsuba draws its four wavelengths with one marginal
distribution (``sample_shifted``), so dropping the same index on every
path only adds colour noise; it is how pbrt-v4 ends secondary wavelengths,
kept to three. A coloured ``param:`` texture (a triple per hit) is refused
there (Mitsuba evaluates its textures at the path's wavelengths, strata takes
RGB); a number per hit and a normal map (``eval_3``, a ``raw`` bitmap) work.
The polarized variants are refused.

Importing registers the plugin for the variant that is set at that moment;
after switching variants call :func:`register` again.

**Evaluated mode.** In a JIT variant (``llvm_*``, ``cuda_*``) a Python BSDF
must see real arrays, not the symbolic ones Dr.Jit traces by default, so the
Dr.Jit flags ``SymbolicLoops`` and ``SymbolicCalls`` must be off: then each
method is called once per bounce with all the lanes that hit the material (a
wavefront batch that strata answers in one call). Importing this module
changes no flag (evaluated mode makes every render of the process slower,
3-4x even with built-in BSDFs): call :func:`enable_evaluated_mode` on the
thread that renders, before ``mi.render``. Dr.Jit's flags are per thread,
which is why constructing the BSDF cannot do it (Mitsuba builds scenes on
worker threads). A ``"strata"`` BSDF called inside a symbolic trace raises a
``RuntimeError`` saying so. The scalar variants need nothing.

**Conventions.** Mitsuba hands a BSDF directions already in the local shading
frame (z = shading normal), as strata wants them. Mitsuba's ``si.wi`` is the
direction the path arrived from (the viewer, for camera paths), its ``eval``
includes ``|cos θ_wo|`` and its transport mode names what the *path*
carries. So a camera path (``TransportMode.Radiance``) is strata's
``transport="importance"`` with strata ``wi = si.wi``, ``wo = wo``, and a
light path (``TransportMode.Importance``) is strata's ``"radiance"``; the
plugin holds one strata ``Bsdf`` per mode. The sampler's numbers
(``sample1``, ``sample2``) are hashed into strata's per-query keys, so each
sample draws a fresh walk; ``eval`` and ``pdf`` are keyed by the directions
(the same pair gives the same answer, and ``pdf`` is the number ``sample``
reported). Delta samples (every event of the walk a smooth interface) are
flagged ``DeltaReflection``/``DeltaTransmission`` with a positive pdf (the
density of strata's non-delta lobes there, as strata reports it); the
others ``GlossyReflection``/``GlossyTransmission``, or ``DiffuseReflection``
for a stack whose only non-delta interface is Lambertian.

``stats`` counts the calls into strata and the time they took, for
measuring the share of a render spent in strata (:func:`reset_stats`).
"""

from __future__ import annotations

import math
import struct
import time

import drjit as dr
import mitsuba as mi
import numpy as np

from . import DELTA, REFLECTION, TRANSMISSION, Bsdf

__all__ = ["register", "enable_evaluated_mode", "stats", "reset_stats", "sample_keys", "sample_key"]

#: Per plugin method: calls, queries (lanes), ``seconds`` spent in the method
#: (wall clock, from its arguments to its returned values: evaluating and
#: converting the inputs, key hashing, the strata calls and building the
#: results) and ``strata_seconds`` spent in the compiled module's batch calls
#: alone.
stats: dict = {}


def reset_stats() -> None:
    """Zeroes :data:`stats`."""
    stats.clear()
    for k in ("eval", "sample", "pdf", "eval_pdf"):
        stats[k] = {"calls": 0, "queries": 0, "seconds": 0.0, "strata_seconds": 0.0}


reset_stats()


def _count(method: str, n: int, t0: float, strata: float) -> None:
    s = stats[method]
    s["calls"] += 1
    s["queries"] += n
    s["seconds"] += time.perf_counter() - t0
    s["strata_seconds"] += strata


def enable_evaluated_mode() -> None:
    """Turns Dr.Jit's symbolic loops and calls off (evaluated mode), which a
    Python BSDF needs in a JIT variant. Call it before loading the scene."""
    dr.set_flag(dr.JitFlag.SymbolicLoops, False)
    dr.set_flag(dr.JitFlag.SymbolicCalls, False)


def _is_jit() -> bool:
    v = mi.variant() or ""
    return not v.startswith("scalar")


_SYMBOLIC = (
    "strata_bsdf.mitsuba: the strata BSDF was called inside a symbolic Dr.Jit trace, where its "
    "arrays have no values; call strata_bsdf.mitsuba.enable_evaluated_mode() before mi.render "
    "(it turns Dr.Jit's SymbolicLoops and SymbolicCalls off)"
)


_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_GOLDEN = np.uint64(0x9E3779B97F4A7C15)


def _mix_inplace(k: np.ndarray) -> np.ndarray:
    """SplitMix64's finalizer, in place on a uint64 array (wrapping
    arithmetic; one temporary array)."""
    t = k >> np.uint64(30)
    k ^= t
    k *= _M1
    np.right_shift(k, np.uint64(27), out=t)
    k ^= t
    k *= _M2
    np.right_shift(k, np.uint64(31), out=t)
    k ^= t
    return k


def sample_keys(u1: np.ndarray, u2x: np.ndarray, u2y: np.ndarray) -> np.ndarray:
    """strata query keys (uint64) from the sampler's numbers: a hash of the
    bits of ``sample1`` and ``sample2``, so distinct samples draw
    independent walks and the same numbers draw the same walk."""
    b = [np.ascontiguousarray(x, dtype=np.float32).view(np.uint32).astype(np.uint64) for x in (u1, u2x, u2y)]
    with np.errstate(over="ignore"):
        k = b[1]
        k <<= np.uint64(32)
        k |= b[0]
        k += _GOLDEN
        _mix_inplace(k)
        b[2] += _GOLDEN
        k ^= b[2]
        return _mix_inplace(k)


_MASK = (1 << 64) - 1


def _mix_int(k: int) -> int:
    k ^= k >> 30
    k = (k * 0xBF58476D1CE4E5B9) & _MASK
    k ^= k >> 27
    k = (k * 0x94D049BB133111EB) & _MASK
    return k ^ (k >> 31)


_F3 = struct.Struct("<3f")
_I3 = struct.Struct("<3I")


def sample_key(u1: float, u2x: float, u2y: float) -> int:
    """:func:`sample_keys` for one sample, on Python numbers (the scalar variants)."""
    b0, b1, b2 = _I3.unpack(_F3.pack(u1, u2x, u2y))  # the float32 bits
    k = _mix_int(((b0 | (b1 << 32)) + 0x9E3779B97F4A7C15) & _MASK)
    return _mix_int(k ^ ((b2 + 0x9E3779B97F4A7C15) & _MASK))


def _width(*xs) -> int:
    return max(dr.width(x) for x in xs)


def _floats(x, n: int) -> np.ndarray:
    """A Mitsuba Float (any width, or a Python scalar) as a contiguous float32
    array of length n."""
    if isinstance(x, (float, int, bool)):
        return np.full(n, x, dtype=np.float32)
    a = np.asarray(x.numpy(), dtype=np.float32).reshape(-1)
    if a.shape[0] != n:
        a = np.broadcast_to(a, (n,))
    return np.ascontiguousarray(a)


def _bools(x, n: int) -> np.ndarray:
    if isinstance(x, (bool, int)):
        return np.full(n, bool(x))
    a = np.asarray(x.numpy(), dtype=bool).reshape(-1)
    if a.shape[0] != n:
        a = np.broadcast_to(a, (n,))
    return a


class _Host:
    """Converts between Mitsuba's values and numpy arrays in the current
    variant (scalar: Python floats; JIT: Dr.Jit arrays, zero-copy)."""

    def __init__(self):
        self.jit = _is_jit()

    def check(self):
        if self.jit and dr.flag(dr.JitFlag.SymbolicScope):
            raise RuntimeError(_SYMBOLIC)

    @staticmethod
    def evaluate(*values):
        """Evaluates a call's Dr.Jit inputs together: one kernel for all of
        them, where converting them one by one would launch one each."""
        dr.eval(*values)

    @staticmethod
    def vec_in(v, n):
        """An evaluated Vector3f as three float32 arrays (views, no copy)."""
        return tuple(_floats(c, n) for c in (v.x, v.y, v.z))

    def float_out(self, a: np.ndarray):
        if self.jit:
            return mi.Float(np.ascontiguousarray(a, dtype=np.float32))
        return float(a[0])

    def uint_out(self, a: np.ndarray):
        if self.jit:
            return mi.UInt32(np.ascontiguousarray(a, dtype=np.uint32))
        return int(a[0])

    def vec_out(self, t):
        return mi.Vector3f(*(self.float_out(c) for c in t))

    def color_out(self, t):
        """RGB (three arrays) as a Color3f, or four wavelengths' values (four
        arrays) as a Spectrum."""
        if len(t) == 4:
            return mi.Spectrum(*(self.float_out(c) for c in t))
        return mi.Color3f(*(self.float_out(c) for c in t))

    def wavelengths_in(self, si, n):
        """The four wavelengths of the lanes of ``si`` (a spectral variant) as
        a float32 array (n, 4)."""
        w = si.wavelengths
        if self.jit:
            return np.stack([_floats(w[i], n) for i in range(4)], axis=1)
        return np.array([[float(w[i]) for i in range(4)]], np.float32)


def _channels(x):
    """A strata result's channels as a list of (n,) arrays: from an (n, 3)
    array (scalar calls) or from three arrays (JIT calls)."""
    if isinstance(x, tuple):
        return list(x)
    return [x[:, c] for c in range(x.shape[1])]


class _Spectral:
    """How the plugin answers Mitsuba's four wavelengths per lane with
    strata's walks, which carry three wavelengths (one where an IOR varies):
    ``groups`` are the strata calls of an eval, each three indices into the
    four ((0, 1, 2) then (3, 3, 3); or (k, k, k) for each k), and a sample
    keeps the wavelengths of the first group and weights them by
    ``4 / kept`` (the others get 0)."""

    def __init__(self, per_walk: int):
        if per_walk == 3:
            self.groups = [(0, 1, 2), (3, 3, 3)]
        else:
            self.groups = [(k, k, k) for k in range(4)]
        self.kept = len(set(self.groups[0]))
        self.scale = np.float32(4 / self.kept)

    def nm(self, nm4, group):
        return np.ascontiguousarray(nm4[:, list(group)])

    def eval(self, call, nm4, n):
        """The four wavelengths' values (a list of (n,) arrays) and the first
        group's pdf (None if ``call`` returns none): ``call(nm)`` is strata's
        eval or eval_pdf at three wavelengths per query."""
        out = [None] * 4
        pdf = None
        for i, group in enumerate(self.groups):
            r = call(self.nm(nm4, group))
            f = _channels(r[0])
            if i == 0 and len(r) == 3:
                pdf = r[2]
            for c, k in enumerate(group):
                if out[k] is None:
                    out[k] = f[c]
        return out, pdf

    def sample_weight(self, weight, n):
        """A sample's weight at the four wavelengths: the kept ones scaled,
        the others 0."""
        w = _channels(weight)
        out = [np.zeros(n, np.float32) for _ in range(4)]
        for c in range(self.kept):
            out[c] = w[c] * self.scale
        return out


def _valid_dirs(wi, active):
    """Lanes that can be queried: active, finite and nonzero; the others get
    +z (and their results are zeroed)."""
    x, y, z = wi
    ok = active & np.isfinite(x) & np.isfinite(y) & np.isfinite(z) & ((x != 0) | (y != 0) | (z != 0))
    if not ok.all():
        wi = tuple(np.where(ok, c, np.float32(d)).astype(np.float32) for c, d in zip(wi, (0.0, 0.0, 1.0)))
    return wi, ok


def _param_width(bsdf, key: str, path: str, mean: float) -> int:
    """3 if the field at ``path`` takes a triple (strata accepts one per
    query), else 1; an error naming the property if it takes neither."""
    wi = np.array([[0.0, 0.0, 1.0]], np.float32)
    err = None
    for width in (3, 1):
        shape = (1, 3) if width == 3 else (1,)
        try:
            bsdf.pdf(wi, wi, params={path: np.full(shape, mean, np.float32)})
            return width
        except ValueError as e:
            err = e
    raise ValueError(f"strata: property {key!r} (parameter {path!r}, texture mean {np.float32(mean)}): {err}")


class _Param:
    """A ``param:`` property: a texture, the strata path it drives, the
    number of floats per query, and the value given to lanes that are not
    queried (the texture's mean)."""

    def __init__(self, key, texture, bsdf):
        self.key = key
        self.path = key[len("param:"):].replace(":", ".")
        self.texture = texture
        self.refresh()
        # A normal map's texels encode n = 2c - 1, always a triple.
        self.normal_map = self.path.endswith(".normal")
        if self.normal_map:
            self.width = 3
        else:
            self.width = _param_width(bsdf, key, self.path, self.mean)

    def refresh(self):
        """Re-reads the texture's mean (after a change through mi.traverse)."""
        m = self.texture.mean()
        try:
            self.mean = float(m)
        except TypeError:  # a JIT variant's Float of width 1
            self.mean = float(m[0])

    def values(self, si, active, n, ok, jit):
        """The texture at the lanes of ``si`` as a float32 array (n,) or (n, 3);
        lanes not ``ok`` get the mean."""
        if self.width == 1:
            v = self.texture.eval_1(si, active)
            if jit:
                dr.eval(v)
            a = _floats(v, n) if jit else np.full(n, float(v), np.float32)
        else:
            # (a spectral variant's eval is at the path's wavelengths; a
            # normal map's raw triple is eval_3)
            c = self.texture.eval_3(si, active) if mi.is_spectral else self.texture.eval(si, active)
            if jit:
                dr.eval(c)  # one kernel for the three channels
                a = np.stack([_floats(c[i], n) for i in range(3)], axis=1)
            else:
                a = np.array([[float(c[0]), float(c[1]), float(c[2])]], np.float32)
        if self.normal_map:
            a = np.float32(2.0) * a - np.float32(1.0)
            unset = np.array([0.0, 0.0, 1.0], np.float32)
        else:
            unset = np.float32(self.mean)
        if ok is not None and not ok.all():
            a = np.where(ok[:, None] if self.width == 3 else ok, a, unset)
        return np.ascontiguousarray(a, dtype=np.float32)


def _make_class():
    F = mi.BSDFFlags

    class StrataBSDF(mi.BSDF):
        """strata's layered BSDF as a Mitsuba BSDF (see the module docstring)."""

        def __init__(self, props):
            mi.BSDF.__init__(self, props)
            if "filename" not in props:
                raise ValueError('strata: the "filename" parameter (a TOML or JSON material) is required')
            name = str(props["filename"])
            path = str(mi.file_resolver().resolve(name))
            # Passed on as given: Bsdf names a value that is not a whole
            # number (or, for pdf_samples, a rule) rather than truncating it.
            samples = props["samples"] if "samples" in props else 1
            seed = props["seed"] if "seed" in props else 0
            pdf_samples = props["pdf_samples"] if "pdf_samples" in props else None
            # Mitsuba's radiance mode (camera paths) is strata's importance mode.
            self._camera = Bsdf.from_path(
                path, samples=samples, seed=seed, transport="importance", pdf_samples=pdf_samples
            )
            if "config" in props:
                # The library's settings as text, after the others.
                self._camera = self._camera.configure(str(props["config"]))
            self._light = self._camera.with_transport("radiance")
            self._filename = name
            self._host = _Host()
            lobes = self._camera.lobes
            n_above, n_below = self._camera.exterior_ior, self._camera.exterior_ior_below
            self._eta_down = np.float32(n_below / n_above)  # wi above, wo below
            self._eta_up = 1 / self._eta_down  # wi below, wo above (float32)
            sides = F.FrontSide
            if lobes["transmission"] or self._camera.two_sided:
                sides = sides | F.BackSide
            comps = []
            self._refl = F.GlossyReflection if lobes["glossy"] else F.DiffuseReflection
            self._trans = F.GlossyTransmission
            types = {}
            if lobes["delta_reflection"]:
                types["dr"] = F.DeltaReflection
            if lobes["delta_transmission"]:
                types["dt"] = F.DeltaTransmission
            if lobes["glossy"] or lobes["diffuse"]:
                types["r"] = self._refl
                if lobes["transmission"]:
                    types["t"] = self._trans
            self._component = {}
            flags = 0
            for i, (k, t) in enumerate(types.items()):
                comps.append(t | sides)
                flags = flags | t | sides
                self._component[k] = i
            self.m_components = comps
            self.m_flags = flags
            # The sampled type and component of each value of strata's flag
            # bits (REFLECTION | TRANSMISSION | DELTA), for the JIT sample;
            # 0 where no bit says reflection or transmission.
            self._stype_of = np.zeros(8, np.uint32)
            self._comp_of = np.zeros(8, np.uint32)
            for fl in range(8):
                delta = bool(fl & DELTA)
                for side, key, t in (
                    (REFLECTION, "dr" if delta else "r", F.DeltaReflection if delta else self._refl),
                    (TRANSMISSION, "dt" if delta else "t", F.DeltaTransmission if delta else self._trans),
                ):
                    if fl & side:  # (transmission wins if both were set)
                        self._stype_of[fl], self._comp_of[fl] = int(t), self._component.get(key, 0)
            self._nondelta = bool(lobes["glossy"] or lobes["diffuse"])
            self._params = [
                _Param(k, props.get_unbounded_texture(k), self._camera)
                for k in sorted(props.keys())
                if k.startswith("param:")
            ]
            if mi.is_polarized:
                raise ValueError("strata: Mitsuba's polarized variants are not supported (strata answers unpolarized light)")
            self._spectral = None
            if mi.is_spectral:
                self._spectral = _Spectral(self._camera.wavelengths_per_walk)
                for p in self._params:
                    if p.width == 3 and not p.normal_map:
                        raise ValueError(
                            f"strata: property {p.key!r}: a coloured texture (a triple per hit) is not supported in "
                            f"Mitsuba's spectral variants yet (Mitsuba hands out its values at the path's "
                            f"wavelengths, strata takes RGB); use an RGB variant, or a number per hit"
                        )

        def _params_at(self, si, active, n, ok=None):
            """The per-query parameters at the lanes of ``si`` (None without
            ``param:`` properties)."""
            if not self._params:
                return None
            jit = self._host.jit
            return {p.path: p.values(si, active, n, ok, jit) for p in self._params}

        def _bsdf(self, ctx):
            return self._camera if ctx.mode == mi.TransportMode.Radiance else self._light

        def _zero(self):
            return mi.Spectrum(0) if self._spectral else mi.Color3f(0)

        def _lane_type(self, flags):
            """(sampled type, component) of one sample's strata flags."""
            if flags & DELTA:
                key, t = ("dr", F.DeltaReflection) if flags & REFLECTION else ("dt", F.DeltaTransmission)
            else:
                key, t = ("r", self._refl) if flags & REFLECTION else ("t", self._trans)
            return int(t), self._component.get(key, 0)

        def _sample_scalar(self, ctx, si, sample1, sample2, active):
            """sample() for the scalar variants: one query, no numpy array arithmetic."""
            t0 = time.perf_counter()
            bs = mi.BSDFSample3f()
            bs.wo, bs.pdf, bs.eta, bs.sampled_type, bs.sampled_component = mi.Vector3f(0), 0.0, 1.0, 0, 0
            v = si.wi  # (each read of si.wi makes a new vector)
            wi = (float(v.x), float(v.y), float(v.z))
            if not (active and all(map(math.isfinite, wi)) and any(wi)):
                return bs, self._zero()
            key = sample_key(float(sample1), float(sample2.x), float(sample2.y))
            params = self._params_at(si, active, 1)
            sp = self._spectral
            nm = sp.nm(self._host.wavelengths_in(si, 1), sp.groups[0]) if sp else None
            t1 = time.perf_counter()
            wo, weight, pdf, flags = self._bsdf(ctx).sample(
                np.array([wi], np.float32), np.array([key], np.uint64), params=params, wavelengths=nm
            )
            t_strata = time.perf_counter() - t1
            fl = int(flags[0])
            stype, comp = self._lane_type(fl) if fl else (0, 0)
            ok = fl != 0 and (int(ctx.type_mask) & stype) != 0
            if ctx.component != 0xFFFFFFFF and ctx.component != -1:
                ok = ok and comp == ctx.component
            _count("sample", 1, t0, t_strata)
            if not ok:
                return bs, self._zero()
            w = wo[0].tolist()
            bs.wo = mi.Vector3f(w[0], w[1], w[2])
            bs.pdf = float(pdf[0])
            if fl & TRANSMISSION:
                bs.eta = float(self._eta_down) if wi[2] > 0 else float(1 / self._eta_down)
            bs.sampled_type, bs.sampled_component = stype, comp
            if sp:
                return bs, mi.Spectrum(*(float(c[0]) for c in sp.sample_weight(weight, 1)))
            r, g, b = weight[0].tolist()
            return bs, mi.Color3f(r, g, b)

        def _eval_scalar(self, ctx, si, wo, active, method):
            """eval/pdf/eval_pdf for the scalar variants."""
            t0 = time.perf_counter()
            v = si.wi
            wi = (float(v.x), float(v.y), float(v.z))
            w = (float(wo.x), float(wo.y), float(wo.z))
            ok = (
                active
                and self._nondelta
                and (int(ctx.type_mask) & int(F.Smooth)) != 0
                and all(map(math.isfinite, wi + w))
                and any(wi)
                and any(w)
            )
            value, pdf = self._zero(), 0.0
            t_strata = 0.0
            if ok:
                bsdf = self._bsdf(ctx)
                a, b = np.array([wi], np.float32), np.array([w], np.float32)
                params = self._params_at(si, active, 1)
                nm4 = self._host.wavelengths_in(si, 1) if self._spectral else None
                t1 = time.perf_counter()
                f, p = self._query(bsdf, a, b, params, nm4, method, 1)
                t_strata = time.perf_counter() - t1
                if method != "pdf":
                    cos = np.float32(abs(float(np.float32(w[2]))))
                    value = (mi.Spectrum if self._spectral else mi.Color3f)(*(float(c[0] * cos) for c in f))
                if method != "eval":
                    pdf = float(p[0])
            _count(method, 1, t0, t_strata)
            return value, pdf

        def _query(self, bsdf, wi, wo, params, nm4, method, n):
            """strata's answers for ``method`` (eval, pdf or eval_pdf): f as a
            list of channel arrays (RGB, or Mitsuba's four wavelengths when
            ``nm4`` holds them), or None for pdf; and the pdf, or None for eval."""
            if method == "pdf":
                nm = self._spectral.nm(nm4, self._spectral.groups[0]) if nm4 is not None else None
                return None, bsdf.pdf(wi, wo, params=params, wavelengths=nm)

            def call(nm):
                if method == "eval_pdf":  # one call: eval's and pdf's numbers
                    return bsdf.eval_pdf(wi, wo, params=params, wavelengths=nm)
                return bsdf.eval(wi, wo, params=params, wavelengths=nm)

            if nm4 is not None:
                return self._spectral.eval(call, nm4, n)
            r = call(None)
            return _channels(r[0]), (r[2] if method == "eval_pdf" else None)

        def sample(self, ctx, si, sample1, sample2, active=True):
            h = self._host
            if not h.jit:
                return self._sample_scalar(ctx, si, sample1, sample2, active)
            h.check()
            t0 = time.perf_counter()
            n = _width(si.wi.x, sample1, sample2.x, active)
            h.evaluate(si.wi, sample1, sample2, active, *([si.wavelengths] if self._spectral else []))
            wi, ok = _valid_dirs(h.vec_in(si.wi, n), _bools(active, n))
            keys = sample_keys(_floats(sample1, n), _floats(sample2.x, n), _floats(sample2.y, n))
            params = self._params_at(si, active, n, ok)
            sp = self._spectral
            nm = sp.nm(h.wavelengths_in(si, n), sp.groups[0]) if sp else None
            t1 = time.perf_counter()
            wo, weight, pdf, flags = self._bsdf(ctx).sample(wi, keys, params=params, wavelengths=nm)
            t_strata = time.perf_counter() - t1
            # Sampled type and component per lane: a table lookup by flags.
            lobe = flags & np.uint32(7)
            stype, comp = self._stype_of[lobe], self._comp_of[lobe]
            ok &= flags != 0
            if int(ctx.type_mask) != int(F.All):
                ok &= (stype & np.uint32(int(ctx.type_mask))) != 0
            if ctx.component != 0xFFFFFFFF and ctx.component != -1:
                ok &= comp == np.uint32(ctx.component)
            # eta of a refraction: IOR on wo's side over wi's side; 1 for a
            # reflection and for lanes not sampled.
            eta = np.ones(n, np.float32)
            refracted = ok & ((flags & TRANSMISSION) != 0)
            eta[refracted] = np.where(wi[2][refracted] > 0, self._eta_down, self._eta_up)
            # strata's arrays are the plugin's own: lanes not sampled are
            # zeroed in place, and the arrays go to Dr.Jit without a copy.
            if sp:
                weight = tuple(sp.sample_weight(weight, n))
            if not ok.all():
                off = ~ok
                for a in (*wo, *weight, pdf, stype):
                    a[off] = 0
            bs = mi.BSDFSample3f()
            bs.wo = h.vec_out(wo)
            bs.pdf = h.float_out(pdf)
            bs.eta = h.float_out(eta)
            bs.sampled_type = h.uint_out(stype)
            bs.sampled_component = h.uint_out(comp)
            value = h.color_out(weight)
            _count("sample", n, t0, t_strata)
            return bs, value

        def _eval(self, ctx, si, wo, active, method):
            """eval/pdf/eval_pdf in the JIT variants: (value, pdf) as Dr.Jit
            arrays (None for the one not asked for)."""
            h = self._host
            h.check()
            t0 = time.perf_counter()
            n = _width(si.wi.x, wo.x, active)
            h.evaluate(si.wi, wo, active, *([si.wavelengths] if self._spectral else []))
            act = _bools(active, n)
            wi, ok = _valid_dirs(h.vec_in(si.wi, n), act)
            w, ok2 = _valid_dirs(h.vec_in(wo, n), act)
            ok &= ok2
            if not self._nondelta or not (int(ctx.type_mask) & int(F.Smooth)):
                ok[:] = False
            # No lane to query (a delta-only stack, a mask without smooth
            # lobes): zeros, without calling strata.
            query = bool(ok.any())
            bsdf = self._bsdf(ctx)
            params = self._params_at(si, active, n, ok) if query else None
            off = None if ok.all() else ~ok
            value = pdf = None
            t_strata = 0.0
            p = None
            nm4 = h.wavelengths_in(si, n) if query and self._spectral else None
            channels = 4 if self._spectral else 3
            if query and method != "pdf":
                t1 = time.perf_counter()
                f, p = self._query(bsdf, wi, w, params, nm4, method, n)
                t_strata += time.perf_counter() - t1
            if method in ("eval", "eval_pdf"):
                if query:
                    # Mitsuba's eval includes |cos wo|: in place, on
                    # strata's arrays (the plugin's own).
                    cos = np.abs(w[2])
                    for c in f:
                        np.multiply(c, cos, out=c)
                        if off is not None:
                            c[off] = 0
                else:
                    f = [np.zeros(n, np.float32) for _ in range(channels)]
                value = h.color_out(f)
            if method in ("pdf", "eval_pdf"):
                if query:
                    if p is None:
                        t1 = time.perf_counter()
                        _, p = self._query(bsdf, wi, w, params, nm4, "pdf", n)
                        t_strata += time.perf_counter() - t1
                    if off is not None:
                        p[off] = 0
                else:
                    p = np.zeros(n, np.float32)
                pdf = h.float_out(p)
            _count(method, n, t0, t_strata)
            return value, pdf

        def eval(self, ctx, si, wo, active=True):
            if not self._host.jit:
                return self._eval_scalar(ctx, si, wo, active, "eval")[0]
            return self._eval(ctx, si, wo, active, "eval")[0]

        def pdf(self, ctx, si, wo, active=True):
            if not self._host.jit:
                return self._eval_scalar(ctx, si, wo, active, "pdf")[1]
            return self._eval(ctx, si, wo, active, "pdf")[1]

        def eval_pdf(self, ctx, si, wo, active=True):
            if not self._host.jit:
                return self._eval_scalar(ctx, si, wo, active, "eval_pdf")
            return self._eval(ctx, si, wo, active, "eval_pdf")

        def traverse(self, callback):
            # The textures, so that mi.traverse reaches their parameters
            # (a bitmap's data): they are evaluated at every call.
            for p in self._params:
                callback.put(p.key, p.texture, mi.ParamFlags.NonDifferentiable)

        def parameters_changed(self, keys):
            for p in self._params:
                p.refresh()

        def to_string(self):
            params = "".join(f", {p.path}={str(p.texture).split('[')[0]}" for p in self._params)
            return f"StrataBSDF[filename={self._filename!r}, {self._camera!r}{params}]"

    return StrataBSDF


_registered: dict = {}


def register() -> None:
    """Registers the BSDF type ``"strata"`` for the current Mitsuba variant
    (done on import; call again after ``mi.set_variant``)."""
    variant = mi.variant()
    if variant is None:
        raise RuntimeError("strata_bsdf.mitsuba: call mitsuba.set_variant(...) before registering")
    if variant in _registered:
        return
    cls = _make_class()
    mi.register_bsdf("strata", lambda props: cls(props))
    _registered[variant] = cls


if mi.variant() is not None:
    register()
