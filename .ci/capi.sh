#!/usr/bin/env bash
# CI for the C ABI (crates/strata-capi), run from the repository root:
#  1. the committed header include/strata.h is what cbindgen makes of the
#     crate now (else: a diff, and a failure);
#  2. the crate builds in release (libstrata_capi.a and .so);
#  3. the C examples and the C tests (abuse, fork) compile against the
#     static library with -Wall -Werror and run, exiting 0.
# The Rust tests of the crate (tests/*.rs) run in the workspace's cargo test.
set -euo pipefail
cd "$(dirname "$0")/.."
export CARGO_TERM_COLOR=never

crate=crates/strata-capi
header=$crate/include/strata.h

# The header is what Debian bookworm's cbindgen (0.24.3) makes; another
# version may format it differently and fail the check below.
if ! command -v cbindgen >/dev/null 2>&1; then
  if [ "$(id -u)" != 0 ]; then
    echo "cbindgen is missing: install it (Debian: apt-get install cbindgen) or run as root" >&2
    exit 1
  fi
  echo "== installing cbindgen"
  apt-get update -qq
  apt-get install -y -qq cbindgen >/dev/null
fi
cbindgen --version
# .ci/run installs ahead, in the background, while the Rust stages run.
if [ "${1:-}" = --install-only ]; then
  exit 0
fi

tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

echo "== $header is up to date"
cbindgen --quiet --config "$crate/cbindgen.toml" --crate strata-capi \
  --output "$tmp/strata.h" "$crate"
if ! diff -u "$header" "$tmp/strata.h"; then
  echo "$header is stale: regenerate it with" >&2
  echo "  cbindgen --config $crate/cbindgen.toml --crate strata-capi --output $header $crate" >&2
  exit 1
fi

# The workspace's default members, as `cargo test` builds them: the C library
# is then the one the suite built (`-p strata-capi` alone would resolve other
# features and build the Rust library again).
echo "== cargo build --release (the workspace; the C library among it)"
cargo build --release
target_dir=$(cargo metadata --format-version 1 --no-deps | sed -n 's/.*"target_directory":"\([^"]*\)".*/\1/p')
lib="$target_dir/release/libstrata_capi.a"
test -f "$lib"

cc=${CC:-cc}
cflags=(-std=c99 -O2 -Wall -Wextra -Werror -I"$crate/include")
libs=(-lpthread -ldl -lm)

run() {
  local name=$1 src=$2
  echo "== $name"
  "$cc" "${cflags[@]}" "$src" "$lib" "${libs[@]}" -o "$tmp/$name"
  local status=0
  "$tmp/$name" || status=$?
  if [ "$status" -ne 0 ]; then
    echo "$name exited with status $status" >&2
    exit 1
  fi
}

run eval_sample "$crate/examples/c/eval_sample.c"
run textured "$crate/examples/c/textured.c"
run abuse "$crate/tests/c/abuse.c"
run fork "$crate/tests/c/fork.c"
run per_query_memory "$crate/tests/c/per_query_memory.c"

# The header also compiles as C++ (its extern "C" guard).
if command -v c++ >/dev/null 2>&1; then
  echo "== strata.h in C++"
  printf '#include "strata.h"\nint main() { return strata_version() == nullptr; }\n' >"$tmp/cpp.cc"
  c++ -std=c++11 -Wall -Werror -I"$crate/include" "$tmp/cpp.cc" "$lib" "${libs[@]}" -o "$tmp/cpp"
  "$tmp/cpp"
fi
echo "capi: ok"
