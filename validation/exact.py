#!/usr/bin/env python3
"""Exact references, computed here in f64 with numpy only (no strata code):

1. Chandrasekhar's H-function: a semi-infinite, index-matched, isotropically scattering medium of
   albedo a reflects  f(wi, wo) = a H(mu_i) H(mu_o) / (4 pi (mu_i + mu_o))  with directional albedo
   R(mu) = 1 - H(mu) sqrt(1 - a). strata's stack is an index-matched slab of optical depth 60; the
   finite depth changes R by less than exp(-2 k 60) (k the diffusion eigenvalue, 0.17 for a = 0.99),
   below 1e-8 for these albedos.
2. A smooth dielectric coat over a Lambertian base with a chromatic absorber between them:
   f = (1 - F(mu_i)) (1 - F(mu_o)) rho exp(-tau/mu_i') exp(-tau/mu_o') / (pi eta^2 (1 - rho r)),
   R(mu) = F(mu) + (1 - F(mu)) exp(-tau/mu') rho t / (1 - rho r), with mu' the refracted cosine,
   r = int_0^1 2 mu F_in(mu) exp(-2 tau/mu) dmu (internal reflection, TIR included) and
   t = int_0^1 2 mu (1 - F_in(mu)) exp(-tau/mu) dmu.
3. A pure absorber between two smooth boundaries (air / n / air): with F = F(mu) and
   A = exp(-tau/mu'),  R = F + (1 - F)^2 F A^2 / (1 - F^2 A^2),  T = (1 - F)^2 A / (1 - F^2 A^2).

Writes validation/references/exact.csv (+ .json) and the material files it refers to.
"""
import json
import math
import os
import platform
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
MAT = os.path.join(HERE, "materials")


def fresnel(cos_i, eta):
    """Unpolarized Fresnel reflectance, light arriving in a region of IOR 1 onto IOR eta
    (eta < 1 for light leaving a denser medium); cos_i > 0."""
    sin2_t = (1.0 - cos_i * cos_i) / (eta * eta)
    if sin2_t >= 1.0:
        return 1.0
    cos_t = math.sqrt(1.0 - sin2_t)
    rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
    return 0.5 * (rs * rs + rp * rp)


def refracted_cos(cos_i, eta):
    return math.sqrt(1.0 - (1.0 - cos_i * cos_i) / (eta * eta))


def gauss01(n):
    x, w = np.polynomial.legendre.leggauss(n)
    return 0.5 * (x + 1.0), 0.5 * w


def integrate(fun, a, b, n=400):
    x, w = gauss01(n)
    xs = a + (b - a) * x
    return float(sum(wi * fun(xi) for xi, wi in zip(xs, w)) * (b - a))


# ---------------------------------------------------------------- H-function
def h_function(a, n=400, iters=2000):
    """H on Gauss nodes by iterating 1/H(mu) = sqrt(1-a) + a/2 int mu' H(mu') / (mu + mu') dmu'."""
    mu, w = gauss01(n)
    h = np.ones(n)
    for _ in range(iters):
        new = 1.0 / (math.sqrt(1.0 - a) + 0.5 * a * ((w * mu * h)[None, :] / (mu[:, None] + mu[None, :])).sum(1))
        if np.max(np.abs(new - h)) < 1e-15:
            h = new
            break
        h = new

    def at(x):
        return 1.0 / (math.sqrt(1.0 - a) + 0.5 * a * float((w * mu * h / (x + mu)).sum()))

    return at


def coat_integrals(eta, tau):
    mu_c = math.sqrt(1.0 - 1.0 / (eta * eta)) if eta > 1 else 0.0  # cosine of the critical angle inside
    # inside, light at cosine mu meets the boundary to air: relative IOR 1/eta
    def fin(m):
        return fresnel(m, 1.0 / eta)
    r = integrate(lambda m: 2 * m * math.exp(-2 * tau / m), 1e-300, mu_c) if mu_c > 0 else 0.0
    r += integrate(lambda m: 2 * m * fin(m) * math.exp(-2 * tau / m), mu_c, 1.0)
    t = integrate(lambda m: 2 * m * (1 - fin(m)) * math.exp(-tau / m), mu_c, 1.0)
    return r, t


def dirs(theta, phi):
    return theta, phi


def main():
    t0 = time.time()
    rows = []

    def add(case, material, q, ti, to, po, vals, bound):
        rows.append(dict(case=case, material=material, quantity=q, theta_i=ti, phi_i=0.0,
                         theta_o="" if to is None else to, phi_o="" if po is None else po, delta_deg="",
                         ref=[float(v) for v in vals], sigma=[0.0] * 3, bound=[float(b) for b in bound]))

    # 1. H-function, one channel set per albedo: the three channels carry three albedos.
    albedos = [0.5, 0.9, 0.99]
    mat = "semi_infinite_isotropic.toml"
    with open(os.path.join(MAT, mat), "w") as f:
        f.write('description = "validation: index-matched isotropic slab, optical depth 60, albedo '
                '(0.5, 0.9, 0.99): semi-infinite (Chandrasekhar H)"\n'
                "[[layers]]\ninterface = { kind = \"dielectric\", ior = 1.0 }\n"
                "medium = { thickness = 1.0, sigma_t = 60.0, albedo = [0.5, 0.9, 0.99] }\n"
                "[[layers]]\ninterface = { kind = \"dielectric\", ior = 1.0 }\n")
    hs = [h_function(a) for a in albedos]
    for h, a in zip(hs, albedos):  # check: int_0^1 H = (2/a) (1 - sqrt(1 - a))
        x, w = gauss01(400)
        assert abs(sum(wi * h(xi) for xi, wi in zip(x, w)) - 2 / a * (1 - math.sqrt(1 - a))) < 1e-12
    hs2 = [h_function(a, n=200) for a in albedos]
    for th in [0.0, 45.0, 75.0]:
        mu = math.cos(math.radians(th))
        vals = [1 - h(mu) * math.sqrt(1 - a) for h, a in zip(hs, albedos)]
        vals2 = [1 - h(mu) * math.sqrt(1 - a) for h, a in zip(hs2, albedos)]
        add("semi_infinite_isotropic", mat, "R", th, None, None, vals,
            [abs(x - y) + 1e-8 for x, y in zip(vals, vals2)])
    for ti, to, po in [(0.0, 0.0, 0.0), (30.0, 60.0, 90.0), (70.0, 20.0, 180.0), (80.0, 80.0, 0.0)]:
        mi_, mo = math.cos(math.radians(ti)), math.cos(math.radians(to))
        vals = [a * h(mi_) * h(mo) / (4 * math.pi * (mi_ + mo)) for h, a in zip(hs, albedos)]
        vals2 = [a * h(mi_) * h(mo) / (4 * math.pi * (mi_ + mo)) for h, a in zip(hs2, albedos)]
        add("semi_infinite_isotropic", mat, "f", ti, to, po, vals,
            [abs(x - y) + 1e-8 * v for x, y, v in zip(vals, vals2, vals)])

    # 2. Smooth coat over Lambertian with a chromatic absorber.
    eta, rho, taus = 1.5, 0.8, [0.1, 0.4, 1.0]
    mat = "smooth_coat_absorber_lambertian.toml"
    with open(os.path.join(MAT, mat), "w") as f:
        f.write('description = "validation: smooth coat 1.5 over a chromatic absorber (tau 0.1, 0.4, 1) '
                'over Lambertian 0.8: closed form"\n'
                "[[layers]]\ninterface = { kind = \"dielectric\", ior = 1.5 }\n"
                "medium = { thickness = 1.0, sigma_t = [0.1, 0.4, 1.0], albedo = 0.0 }\n"
                "[[layers]]\ninterface = { kind = \"diffuse\", albedo = 0.8 }\n")
    ints = [coat_integrals(eta, tau) for tau in taus]
    for ti, to, po in [(0.0, 0.0, 0.0), (30.0, 45.0, 180.0), (60.0, 15.0, 30.0), (80.0, 50.0, 90.0)]:
        ci, co = math.cos(math.radians(ti)), math.cos(math.radians(to))
        ci2, co2 = refracted_cos(ci, eta), refracted_cos(co, eta)
        vals = [(1 - fresnel(ci, eta)) * (1 - fresnel(co, eta)) * rho * math.exp(-tau / ci2) * math.exp(-tau / co2)
                / (math.pi * eta * eta * (1 - rho * r)) for tau, (r, _t) in zip(taus, ints)]
        add("smooth_coat_absorber_lambertian", mat, "f", ti, to, po, vals, [1e-9 * v for v in vals])
    for th in [0.0, 45.0, 80.0]:
        c = math.cos(math.radians(th))
        c2 = refracted_cos(c, eta)
        F = fresnel(c, eta)
        vals = [F + (1 - F) * math.exp(-tau / c2) * rho * t / (1 - rho * r) for tau, (r, t) in zip(taus, ints)]
        add("smooth_coat_absorber_lambertian", mat, "R", th, None, None, vals, [1e-9] * 3)

    # 3. Pure absorber between smooth boundaries, two IORs.
    for n, taus, name in [(1.5, [0.05, 0.5, 2.0], "absorbing_slab_1_5"), (1.33, [0.2, 1.0, 3.0], "absorbing_slab_1_33")]:
        mat = name + ".toml"
        with open(os.path.join(MAT, mat), "w") as f:
            f.write(f'description = "validation: smooth slab of IOR {n}, chromatic absorber (tau {taus}), air on both sides: closed form"\n'
                    f"[[layers]]\ninterface = {{ kind = \"dielectric\", ior = {n} }}\n"
                    f"medium = {{ thickness = 1.0, sigma_t = {taus}, albedo = 0.0 }}\n"
                    "[[layers]]\ninterface = { kind = \"dielectric\", ior = 1.0 }\n")
        for th in [0.0, 40.0, 75.0]:
            c = math.cos(math.radians(th))
            c2 = refracted_cos(c, n)
            F = fresnel(c, n)
            A = [math.exp(-tau / c2) for tau in taus]
            add(name, mat, "R", th, None, None, [F + (1 - F) ** 2 * F * x * x / (1 - F * F * x * x) for x in A], [1e-12] * 3)
            add(name, mat, "T", th, None, None, [(1 - F) ** 2 * x / (1 - F * F * x * x) for x in A], [1e-12] * 3)

    dt = time.time() - t0
    cols = ["case", "material", "quantity", "theta_i", "phi_i", "theta_o", "phi_o", "delta_deg"]
    out = os.path.join(HERE, "references", "exact.csv")
    with open(out, "w") as f:
        f.write(",".join(cols + ["ref0", "ref1", "ref2", "sigma0", "sigma1", "sigma2", "bound0", "bound1", "bound2"]) + "\n")
        for r in rows:
            f.write(",".join([str(r[c]) for c in cols] + [repr(x) for x in r["ref"] + r["sigma"] + r["bound"]]) + "\n")
    with open(os.path.splitext(out)[0] + ".json", "w") as f:
        json.dump({"tool": "validation/exact.py (numpy, f64)", "numpy": np.__version__,
                   "python": platform.python_version(), "command": " ".join(["python3"] + sys.argv),
                   "bound": "H-function: |H(400 Gauss nodes) - H(200)| + 1e-8 (finite depth 60); "
                            "closed forms: quadrature and rounding, 1e-9 relative",
                   "seconds": round(dt, 1)}, f, indent=1)
    print(f"{len(rows)} rows in {dt:.1f} s")


if __name__ == "__main__":
    main()
