#!/usr/bin/env bash
# Fuzzing with libFuzzer (docs/testing.md#fuzzing).
#   scripts/fuzz.sh smoke          build the targets in build-fuzz/ and run each over its seed
#                                  corpus plus FUZZ_RUNS new inputs (default 4000), at most 90 s
#                                  per target (CI: a few minutes)
#   scripts/fuzz.sh long [SECONDS] run each target for SECONDS (default 3600) on 1 core, growing
#                                  the corpus in build-fuzz/corpus/<target>
# A crash leaves the input in build-fuzz/crash-*; reproduce with build-fuzz/bin/<target> FILE.
set -euo pipefail
cd "$(dirname "$0")/.."
mode=${1:-smoke}
seconds=${2:-3600}
runs=${FUZZ_RUNS:-4000}
build=build-fuzz
if [ ! -f "$build/CMakeCache.txt" ]; then
  CC=clang CXX=clang++ cmake -S . -B "$build" -DCOSIM_FUZZ=ON -DCMAKE_BUILD_TYPE=Debug >/dev/null
fi
cmake --build "$build" -j"$(nproc)" --target fuzz_messages fuzz_datagrams fuzz_config fuzz_stl fuzz_seeds
mkdir -p "$build/corpus"
for t in messages datagrams config stl; do mkdir -p "$build/corpus/$t"; done
"$build/bin/fuzz_seeds" "$build/corpus/messages" "$build/corpus/datagrams"
# Seeds: the committed corpus (hand-written seeds and every crash found so far, as regression
# cases) and, for the config reader, the project's own configs with the selector byte in front.
for f in configs/oscillator.yaml configs/wheel_loader.yaml configs/hauler.yaml; do
  { printf '\000'; cat "$f"; } >"$build/corpus/config/master_$(basename "$f")"
done
for f in configs/dem/*.yaml; do
  { printf '\001'; cat "$f"; } >"$build/corpus/config/dem_$(basename "$f")"
done
export ASAN_OPTIONS=detect_leaks=0:abort_on_error=1
export UBSAN_OPTIONS=print_stacktrace=1
status=0
for t in messages datagrams config stl; do
  args=(-rss_limit_mb=2048 -malloc_limit_mb=512 -timeout=10 -max_len=65536 -seed=1
        -artifact_prefix="$build/crash-$t-")
  if [ "$mode" = long ]; then
    args+=(-max_total_time="$seconds")
  else
    args+=(-runs="$runs" -max_total_time=90)  # whichever comes first
  fi
  echo "fuzz: $t (${mode})"
  if ! "$build/bin/fuzz_$t" "${args[@]}" "$build/corpus/$t" "tests/fuzz/corpus/$t" \
      >"$build/fuzz_$t.log" 2>&1; then
    echo "fuzz: $t FAILED; the input is in $build/crash-$t-*; log: $build/fuzz_$t.log"
    tail -40 "$build/fuzz_$t.log"
    status=1
  else
    grep -E "^#[0-9]+.*DONE|Done [0-9]+ runs" "$build/fuzz_$t.log" | tail -1 || true
  fi
done
exit $status
