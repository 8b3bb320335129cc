#!/usr/bin/env python3
"""The references against each other, without strata: a reference can be wrong too.

1. Mitsuba's measurement (mitsuba.csv, case smooth_coat_lambertian) against the closed form of a
   smooth coat over a Lambertian base: albedos directly, cone integrals by quadrature of the
   closed form over the same cone.
2. iadpython against the exact absorbing Fresnel slab (a = 0) and against Chandrasekhar's
   H-function (n = 1, optical depth 60).
3. Mitsuba (mitsuba_smooth.csv) against iadpython on the smooth scattering slab at normal
   incidence.

Prints a markdown table (docs/validation.md quotes it). Needs numpy and iadpython (+ scipy).
"""
import csv
import math
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import exact  # noqa: E402


def coat_f(ci, co, eta, rho, r):
    return ((1 - exact.fresnel(ci, eta)) * (1 - exact.fresnel(co, eta)) * rho
            / (math.pi * eta * eta * (1 - rho * r)))


def coat_R(c, eta, rho, r, t):
    F = exact.fresnel(c, eta)
    return F + (1 - F) * rho * t / (1 - rho * r)


def cone_integral(fun, axis_theta, delta, n=64):
    """int over the cone of half-angle delta around (theta, phi = 0) of fun(cos theta_w) cos theta_w."""
    ax = np.array([math.sin(axis_theta), 0.0, math.cos(axis_theta)])
    t = np.cross([0.0, 0.0, 1.0] if abs(ax[2]) < 0.9 else [1.0, 0.0, 0.0], ax)
    t /= np.linalg.norm(t)
    b = np.cross(ax, t)
    x, w = exact.gauss01(n)
    total = 0.0
    for u, wu in zip(x, w):
        cos_a = 1 - u * (1 - math.cos(delta))
        sin_a = math.sqrt(max(0.0, 1 - cos_a * cos_a))
        for v, wv in zip(x, w):
            phi = 2 * math.pi * v
            d = sin_a * math.cos(phi) * t + sin_a * math.sin(phi) * b + cos_a * ax
            total += wu * wv * fun(d[2]) * d[2]
    return total * 2 * math.pi * (1 - math.cos(delta))


def main():
    rows = []
    eta, rhos = 1.5, [0.0, 0.5, 1.0]
    r, t = exact.coat_integrals(eta, 0.0)
    path = os.path.join(HERE, "references", "mitsuba.csv")
    with open(path) as f:
        for m in csv.DictReader(f):
            if m["case"] != "smooth_coat_lambertian":
                continue
            for c in (0, 1, 2):
                rho = rhos[c]
                if rho == 0.0 and m["quantity"] != "R":
                    continue  # f = 0 exactly, and Mitsuba gives exactly 0
                if m["quantity"] == "R":
                    ref = coat_R(math.cos(math.radians(float(m["theta_i"]))), eta, rho, r, t)
                    q = f"R(θi {float(m['theta_i']):g}°)"
                else:
                    co = math.cos(math.radians(float(m["theta_o"])))
                    ref = cone_integral(lambda ci: coat_f(ci, co, eta, rho, r),
                                        math.radians(float(m["theta_i"])), math.radians(float(m["delta_deg"])))
                    q = f"∫cone f cos(θi {float(m['theta_i']):g}°, θo {float(m['theta_o']):g}°)"
                val, sig = float(m[f"ref{c}"]), float(m[f"sigma{c}"])
                rows.append(("Mitsuba vs closed form", f"smooth coat / Lambertian {rho}", q,
                             f"{val:.6g} ± {sig:.1e}", f"{ref:.6g}", f"{(val - ref) / sig:+.2f}"))
    try:
        import iadpython
    except ImportError:
        iadpython = None
    if iadpython is not None:
        for n, b in [(1.5, 0.5), (1.33, 2.0)]:
            s = iadpython.Sample(a=0.0, b=b, g=0.0, d=1.0, n=n, n_above=1.0, n_below=1.0, quad_pts=48)
            ur1, ut1, _, _ = s.rt()
            F = exact.fresnel(1.0, n)
            A = math.exp(-b)
            R = F + (1 - F) ** 2 * F * A * A / (1 - F * F * A * A)
            T = (1 - F) ** 2 * A / (1 - F * F * A * A)
            rows.append(("iadpython vs closed form", f"absorbing slab n {n}, τ {b}", "R, T (θi 0°)",
                         f"{float(ur1):.8f}, {float(ut1):.8f}", f"{R:.8f}, {T:.8f}",
                         f"Δ {abs(float(ur1) - R):.0e}, {abs(float(ut1) - T):.0e}"))
        for a in [0.5, 0.9, 0.99]:
            s = iadpython.Sample(a=a, b=60.0, g=0.0, d=1.0, n=1.0, n_above=1.0, n_below=1.0, quad_pts=24)
            ur1, _, _, _ = s.rt()
            h = exact.h_function(a)
            R = 1 - h(1.0) * math.sqrt(1 - a)
            rows.append(("iadpython vs H-function", f"semi-infinite isotropic, a {a}", "R (θi 0°)",
                         f"{float(ur1):.8f}", f"{R:.8f}", f"Δ {abs(float(ur1) - R):.0e}"))
    # 3. Mitsuba against adding-doubling: the smooth scattering slab at normal incidence.
    smooth = os.path.join(HERE, "references", "mitsuba_smooth.csv")
    if os.path.exists(smooth):
        with open(os.path.join(HERE, "references", "iad.csv")) as f:
            iad = [r for r in csv.DictReader(f) if (float(r["ior"]), float(r["tau"]), float(r["albedo"]),
                                                    float(r["g"])) == (1.5, 1.0, 0.9, 0.5)][0]
        with open(smooth) as f:
            for m in csv.DictReader(f):
                if m["quantity"] in ("R", "T") and float(m["theta_i"]) == 0.0:
                    q = m["quantity"]
                    val, sig = float(m["ref0"]), float(m["sigma0"])
                    ref, qerr = float(iad[q]), float(iad["quad_err_" + q])
                    rows.append(("Mitsuba vs iadpython", "smooth slab n 1.5, τ 1, a 0.9, g 0.5", f"{q} (θi 0°)",
                                 f"{val:.6f} ± {sig:.1e}", f"{ref:.6f} (quadrature {qerr:.0e})",
                                 f"{(val - ref) / sig:+.2f}"))
    print("| check | stack | quantity | tested reference | exact | z or Δ |")
    print("|---|---|---|---|---|---|")
    for row in rows:
        print("| " + " | ".join(row) + " |")


if __name__ == "__main__":
    main()
