#!/usr/bin/env python3
"""Makes the comparison table of docs/validation.md from a strata run of the validation test.

    STRATA_VALIDATION_OUT=/tmp/val cargo test --release -p strata-bsdf --test physics validation::
    python3 validation/table.py /tmp/val          # rewrites the table in docs/validation.md

The test writes one CSV per reference file (exact.csv.strata.csv, mitsuba.csv.strata.csv,
iad.csv.strata.csv) with strata's value and standard error of each run (the wavefront engine with seeds 1 and
2; seed 1's walks are the scalar reference's) beside the stored reference; this script pairs
the two runs and puts every comparison in one table between
the markers <!-- table:begin --> and <!-- table:end -->. Standard library only.
"""
import csv
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
DOC = os.path.join(HERE, "..", "docs", "validation.md")
FILES = [("exact.csv", "exact"), ("mitsuba.csv", "Mitsuba 3.9.1"),
         ("mitsuba_validation1.csv", "Mitsuba 3.9.1"), ("mitsuba_below.csv", "Mitsuba 3.9.1"),
         ("mitsuba_glass.csv", "Mitsuba 3.9.1"), ("mitsuba_smooth.csv", "Mitsuba 3.9.1"),
         ("iad.csv", "iadpython 0.5.3")]
CHANNEL = {"0": "r", "1": "g", "2": "b", "grey": "grey"}


def fmt(v, s):
    v, s = float(v), float(s)
    if v != 0 and abs(v) < 1e-2:
        return f"{v:.4e} ± {s:.1e}"
    return f"{v:.5f} ± {s:.1e}"


def query(r):
    q = r["quantity"]
    if q in ("R", "T"):
        return f"{q}(θi {float(r['theta_i']):g}°)"
    name = "f" if q == "f" else "∫cone f cos"
    return f"{name}(θi {float(r['theta_i']):g}°, θo {float(r['theta_o']):g}°, φo {float(r['phi_o']):g}°)"


def main():
    out = sys.argv[1]
    lines = ["| reference | stack | quantity | ch | strata seed 1 ± σ | strata seed 2 ± σ | "
             "reference ± σ (bound) | z seed 1 | z seed 2 |",
             "|---|---|---|---|---|---|---|---|---|"]
    worst, count = 0.0, 0
    for fname, label in FILES:
        path = os.path.join(out, fname + ".strata.csv")
        with open(path) as f:
            rows = list(csv.DictReader(f))
        by_key = {}
        for r in rows:
            key = (r["case"], r["quantity"], r["theta_i"], r["theta_o"], r["phi_o"], r["channel"])
            by_key.setdefault(key, {})[r["run"]] = r
        for key, eng in by_key.items():
            s, w = eng["seed1"], eng["seed2"]
            bound = float(s["bound"])
            ref = fmt(s["reference"], s["reference_sigma"]) + (f" ({bound:.0e})" if bound > 0 else "")
            lines.append(f"| {label} | {key[0]} | {query(s)} | {CHANNEL[key[5]]} | "
                         f"{fmt(s['strata'], s['strata_sigma'])} | {fmt(w['strata'], w['strata_sigma'])} | "
                         f"{ref} | {float(s['z']):+.2f} | {float(w['z']):+.2f} |")
            worst = max(worst, abs(float(s["z"])), abs(float(w["z"])))
            count += 2
    table = "\n".join(lines)
    text = open(DOC).read()
    a, b = text.index("<!-- table:begin -->"), text.index("<!-- table:end -->")
    text = text[:a] + "<!-- table:begin -->\n" + table + "\n" + text[b:]
    open(DOC, "w").write(text)
    print(f"{count} comparisons; largest |z| before subtracting bounds {worst:.2f}")


if __name__ == "__main__":
    main()
