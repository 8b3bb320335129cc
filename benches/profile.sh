#!/usr/bin/env bash
# Where each engine's time goes, by kind of work, on each representative
# stack: the two profile tables of docs/performance.md.
#
#   bash benches/profile.sh            # needs `perf`; about two minutes
#
# Builds strata with the `profiling` feature (the wavefront's stages and the
# kernels kept out of line, so that perf attributes time to each; a few
# percent slower), runs `strata bench --only ENGINE` (one thread) under
# `perf record` per stack and engine, and sums perf's per-function shares:
#
# 1. the wavefront's time by kind of work (physics, walk start, moving walks,
#    reduction, other);
# 2. both engines' time per query by kind of work they share (the kernels,
#    the walk logic around them, seeding the streams), and the speed-up of
#    the wavefront on each: scalar time ÷ wavefront time, per query.
set -euo pipefail
cd "$(dirname "$0")/.."
target=${CARGO_TARGET_DIR:-target}/profiling
CARGO_PROFILE_RELEASE_DEBUG=line-tables-only \
  cargo build --release --quiet -p strata-cli --features profiling --target-dir "$target"
bin=$target/release/strata
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
for m in clear_coat_lambertian coated_copper thick_scattering scattering_slab three_interfaces; do
  for e in scalar wavefront; do
    perf record -q -o "$tmp/perf.data" "$bin" bench --only "$e" --queries 96 --json \
      --min-seconds 4 --material "examples/materials/$m.toml" >"$tmp/bench.json" 2>/dev/null
    qps=$(sed -E 's/.*"queries_per_s":([0-9.e+-]+).*/\1/' "$tmp/bench.json")
    perf report -i "$tmp/perf.data" --no-children --stdio --sort symbol 2>/dev/null |
      awk -v m="$m" -v e="$e" -v q="$qps" '/^ +[0-9.]+%/ {
        p = $1; sub("%", "", p); $1 = ""; print m "\t" e "\t" q "\t" p "\t" $0 }'
  done
done >"$tmp/shares.tsv"
python3 - "$tmp/shares.tsv" <<'EOF'
import collections, re, sys

# Table 1: the wavefront's time by kind of work.
def kind(s):
    if re.search(r"InterfaceLanes<L>::|interface_event|layer_event|connect_links|full_crossing|run_deferred|MediumLanes|medium::", s):
        return "physics"
    if re.search(r"seed_state|start_walks|launch_chain|Walks::claim|Chunk<W>::start", s):
        return "start"
    if re.search(r"Chunk<W>::|enqueue|finish_lanes|memmove|memset|FnMut<A> for &F>::call_mut|run_task|Wavefront<W>::run::|advance", s):
        return "moving"
    if re.search(r"Map<I,F> as core::iter::traits::iterator::Iterator>::fold|MeanVar|BlockReducer", s):
        return "reduction"
    return "other"

# Table 2: work both engines do, and the wavefront's own bookkeeping.
def shared(s):
    if re.search(r"InterfaceLanes<L>::|MediumLanes<L>::|medium::", s):
        return "kernels"
    if re.search(r"ScalarEngine|interface_event|layer_event|connect_links|full_crossing|run_deferred|launch_chain", s):
        return "logic"
    if re.search(r"seed_state|WalkRng::(new|from_prefix)", s):
        return "seeding"
    return "wavefront only"

share = collections.defaultdict(lambda: collections.defaultdict(float))
qps = {}
stacks = []
for line in open(sys.argv[1]):
    m, e, q, p, s = line.rstrip("\n").split("\t")
    if m not in stacks:
        stacks.append(m)
    qps[(m, e)] = float(q)
    p = float(p) / 100
    if e == "wavefront":
        share[(m, "kind")][kind(s)] += p
    share[(m, e)][shared(s)] += p

print("| stack | physics | walk start | moving walks | reduction | other |")
print("|---|---:|---:|---:|---:|---:|")
for m in stacks:
    t = share[(m, "kind")]
    cols = " | ".join(f"{100 * t[k]:.0f} %" for k in ["physics", "start", "moving", "reduction", "other"])
    print(f"| {m} | {cols} |")

print()
print("| stack | wavefront ÷ scalar | kernels | walk logic | seeding | wavefront only |")
print("|---|---:|---:|---:|---:|---:|")
for m in stacks:
    s, w = share[(m, "scalar")], share[(m, "wavefront")]
    qs, qw = qps[(m, "scalar")], qps[(m, "wavefront")]
    def cell(k):
        # Shares of each engine's time, and scalar ÷ wavefront time per query.
        up = (s[k] / qs) / (w[k] / qw) if w[k] > 0 else float("nan")
        return f"{100 * s[k]:.0f} / {100 * w[k]:.0f} %, {up:.1f}×"
    cells = " | ".join(cell(k) for k in ["kernels", "logic", "seeding"])
    print(f"| {m} | {qw / qs:.2f} | {cells} | {100 * w['wavefront only']:.0f} % |")
EOF
