#!/usr/bin/env bash
# Where the wavefront engine's time goes, by kind of work, on each
# representative stack: the breakdown table of docs/performance.md.
#
#   bash benches/profile.sh            # needs `perf`; about a minute
#
# Builds strata with the `profiling` feature (the wavefront's stages kept out
# of line, so that perf attributes time to each; a few percent slower), runs
# `strata bench --only wavefront` (one thread) under `perf record` per stack,
# and sums perf's per-function shares into the categories below.
set -euo pipefail
cd "$(dirname "$0")/.."
target=${CARGO_TARGET_DIR:-target}/profiling
cargo build --release --quiet --features profiling --target-dir "$target"
bin=$target/release/strata
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
echo "| stack | physics | walk start | moving walks | reduction | other |"
echo "|---|---:|---:|---:|---:|---:|"
for m in clear_coat_lambertian coated_copper thick_scattering scattering_slab three_interfaces; do
  perf record -q -o "$tmp/perf.data" "$bin" bench --only wavefront --queries 96 \
    --min-seconds 4 --material "examples/materials/$m.toml" >/dev/null 2>&1
  perf report -i "$tmp/perf.data" --no-children --stdio --sort symbol 2>/dev/null |
    awk -v stack="$m" '
      /^ +[0-9.]+%/ {
        p = $1; sub("%", "", p); $1 = ""; s = $0
        if (s ~ /InterfaceLanes<L>::|interface_event|layer_event|connect_links|full_crossing|run_deferred|MediumLanes|medium::/) c = "physics"
        else if (s ~ /seed_state|start_walks|launch_chain|Walks::claim|Chunk<W>::start/) c = "start"
        else if (s ~ /Chunk<W>::|enqueue|finish_lanes|memmove|memset|FnMut<A> for &F>::call_mut|run_task|Wavefront<W>::run::|advance/) c = "moving"
        else if (s ~ /Map<I,F> as core::iter::traits::iterator::Iterator>::fold|MeanVar|BlockReducer/) c = "reduction"
        else c = "other"
        t[c] += p
      }
      END { printf "| %s | %.0f %% | %.0f %% | %.0f %% | %.0f %% | %.0f %% |\n", stack,
            t["physics"], t["start"], t["moving"], t["reduction"], t["other"] }'
done
