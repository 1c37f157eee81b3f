#!/usr/bin/env bash
# mpi_local_test: mpi_probe (tests/mpi_hosts/mpi_probe.cpp) with plain mpirun on this host, 2 and 3
# ranks: the sums, the ring's bytes and checksums, the rank count and the host are right; then
# the probe's checks fail where they must (one host is not three; a wrong rank count; a bad
# option), so a pass above means something.
set -uo pipefail
probe=$1
command -v mpirun >/dev/null || { echo "FAIL: no mpirun: install openmpi-bin (bash scripts/setup.sh)"; exit 1; }
# As root (CI) mpirun needs the flag; more ranks than cores need --oversubscribe.
mpirun=(mpirun --allow-run-as-root --oversubscribe)
fails=0
out=$(mktemp); trap 'rm -f "$out"' EXIT

expect_pass() {  # NAME EXPECTED_SUMMARY MPIRUN_AND_PROBE_ARGS...
  local name=$1 want=$2; shift 2
  if ! timeout 60 "${mpirun[@]}" "$@" >"$out" 2>&1; then
    echo "FAIL: $name: mpirun exited non-zero"; cat "$out"; fails=$((fails + 1)); return
  fi
  if ! grep -q "$want" "$out"; then
    echo "FAIL: $name: no '$want' in the output"; cat "$out"; fails=$((fails + 1)); return
  fi
  echo "ok: $name"; grep "mpi_probe:" "$out"
}
expect_fail() {  # NAME EXPECTED_MESSAGE MPIRUN_AND_PROBE_ARGS...
  local name=$1 want=$2; shift 2
  if timeout 60 "${mpirun[@]}" "$@" >"$out" 2>&1; then
    echo "FAIL: $name: mpirun exited 0, a failure was expected"; cat "$out"; fails=$((fails + 1)); return
  fi
  if ! grep -q -- "$want" "$out"; then
    echo "FAIL: $name: failed without '$want'"; cat "$out"; fails=$((fails + 1)); return
  fi
  echo "ok: $name (refused: $want)"
}

expect_pass "2 ranks" "2 ranks on 1 hosts, ring 4 MB x 2 rounds: all checks passed" \
  -np 2 "$probe" --ranks 2 --same-host
expect_pass "3 ranks" "3 ranks on 1 hosts, ring 2 MB x 3 rounds: all checks passed" \
  -np 3 "$probe" --ranks 3 --same-host --mb 2 --rounds 3
expect_fail "3 ranks on one host are not 3 hosts" "asks for one rank per host" \
  -np 3 "$probe" --distinct-hosts --mb 1
expect_fail "wrong rank count" "the job has 2 ranks, --ranks asks for 4" \
  -np 2 "$probe" --ranks 4 --mb 1
expect_fail "bad option" "--mb 0: expected an integer in \[1, 256\]" \
  -np 2 "$probe" --mb 0

[ "$fails" -eq 0 ] || { echo "mpi_local_test: $fails check(s) failed"; exit 1; }
echo "mpi_local_test: all checks passed"
