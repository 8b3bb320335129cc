"""The table of README.md from the two result files beside this script."""
import json, os
HERE = os.path.dirname(os.path.abspath(__file__))
M = [json.loads(l) for l in open(os.path.join(HERE, "mitsuba_results.jsonl"))]
S = [json.loads(l) for l in open(os.path.join(HERE, "strata_results_batched.jsonl"))]
def key(r): return (r["ti"], r["to"], r["po"], r["delta"])
sd = {(os.path.basename(r["material"]),) + key(r): r for r in S}
print("| θi θo φo δ | Mitsuba cone-mean f | strata sep cone | z | strata corr cone | z | strata point sep / corr | Mitsuba s |")
print("|---|---|---|---|---|---|---|---|")
for m in M:
    k = key(m); s = sd[("sep.toml",) + k]; c = sd[("corr.toml",) + k]
    zs = (s["f_mean"] - m["f_mean"]) / (s["sigma_f"]**2 + m["sigma_f"]**2) ** .5
    zc = (c["f_mean"] - m["f_mean"]) / (c["sigma_f"]**2 + m["sigma_f"]**2) ** .5
    print(f"| {k[0]:g} {k[1]:g} {k[2]:g} {k[3]:g}° | {m['f_mean']:.5g} ± {m['sigma_f']:.2g} | {s['f_mean']:.5g} ± {s['sigma_f']:.2g} | {zs:+.2f} | {c['f_mean']:.5g} ± {c['sigma_f']:.2g} | {zc:+.2f} | {s['point_f']:.5g} ± {s['point_sigma']:.1g} / {c['point_f']:.5g} ± {c['point_sigma']:.1g} | {m['seconds']} |")
