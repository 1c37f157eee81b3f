#!/usr/bin/env bash
# mpi_slurm_script_test: scripts/slurm/dem_mpi.sbatch without Slurm. Its syntax (bash -n); its
# #SBATCH options against sbatch's documented options (sbatch --help where Slurm is installed);
# then the script itself, run by bash with the variables Slurm would set (1 rank x 1 thread on
# this host): `run` with dem_run on a short scene and `cosim` with cosim_master, the prescribed
# blade and dem_service under mpirun, so that every option it gives mpirun, dem_run,
# dem_service and cosim_master is used for real; and it fails where it must (an unknown mode,
# binaries that are not there, an option dem_run does not know).
set -uo pipefail
src=$1 bin=$2
script="$src/scripts/slurm/dem_mpi.sbatch"
work=$(mktemp -d); trap 'rm -rf "$work"' EXIT
fails=0
fail() { echo "FAIL: $*"; fails=$((fails + 1)); }
ok() { echo "ok: $*"; }

bash -n "$script" && ok "bash -n" || fail "bash -n $script"

# sbatch's long options (Slurm 22.05, the sbatch man page), or sbatch --help where installed.
known="account array batch begin chdir cluster-constraint clusters comment constraint container
contiguous core-spec cores-per-socket cpu-freq cpus-per-gpu cpus-per-task deadline delay-boot
dependency distribution error exclude exclusive export export-file extra-node-info get-user-env
gid gpu-bind gpu-freq gpus gpus-per-node gpus-per-socket gpus-per-task gres gres-flags hint hold
ignore-pbs input job-name kill-on-invalid-dep licenses mail-type mail-user mcs-label mem
mem-bind mem-per-cpu mem-per-gpu mincpus network nice no-kill no-requeue nodefile nodelist
nodes ntasks ntasks-per-core ntasks-per-gpu ntasks-per-node ntasks-per-socket open-mode output
overcommit oversubscribe parsable partition power prefer priority profile propagate qos quiet
reboot requeue reservation signal sockets-per-node spread-job switches test-only thread-spec
threads-per-core time time-min tmp uid use-min-nodes verbose wait wait-all-nodes wckey wrap"
if command -v sbatch >/dev/null; then
  known=$(sbatch --help | grep -o -- '--[a-z-]*' | sed 's/^--//' | sort -u)
fi
n_opts=0
while read -r opt; do
  n_opts=$((n_opts + 1))
  grep -qx -- "$opt" <<<"$(tr ' ' '\n' <<<"$known")" || fail "#SBATCH --$opt is no sbatch option"
done < <(sed -n 's/^#SBATCH --\([a-z-]*\).*/\1/p' "$script")
[ "$n_opts" -ge 4 ] && ok "$n_opts #SBATCH options are sbatch's" || fail "only $n_opts #SBATCH lines found"

# What Slurm sets for `sbatch --ntasks=1 --cpus-per-task=1`; as root (CI) mpirun needs the
# variables below.
slurm_env=(env SLURM_SUBMIT_DIR="$src" SLURM_NTASKS=1 SLURM_CPUS_PER_TASK=1 SOILCOSIM_BIN="$bin"
           OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMP_WAIT_POLICY=PASSIVE)

# run: dem_run on the dem_service tests' scene (1500 grains, a blade) for 100 steps.
out="$work/run.h5"
if timeout 120 "${slurm_env[@]}" bash "$script" run tests/dem_service/scene.yaml --set run.duration=0.001 \
    --output "$out" >"$work/run.log" 2>&1; then
  if grep -q "bound to" "$work/run.log" && [ -s "$out" ]; then ok "run: dem_run under mpirun wrote $out"
  else fail "run: no binding report or no output"; cat "$work/run.log"; fi
else
  fail "run: the script failed"; cat "$work/run.log"
fi

# cosim: the master and the prescribed blade, dem_service under mpirun joining by hand.
out="$work/cosim.h5"
if timeout 180 "${slurm_env[@]}" DEM_CONFIG=tests/dem_service/scene.yaml DEM_PARTICIPANT=dem \
    bash "$script" cosim tests/dem_service/cosim.yaml --set time.end=0.001 --output "$out" \
    >"$work/cosim.log" 2>&1; then
  status=$(/usr/bin/python3 -c "import h5py,sys; f=h5py.File(sys.argv[1]); s=f['status'][()]; print(s.decode() if isinstance(s, bytes) else s)" "$out" 2>&1)
  if [ "$status" = finished ]; then ok "cosim: the co-simulation finished ($out)"
  else fail "cosim: status '$status'"; cat "$work/cosim.log"; fi
else
  fail "cosim: the script failed"; cat "$work/cosim.log"
fi

# Failures it must report.
expect_fail() {  # WHAT MESSAGE COMMAND...
  local what=$1 msg=$2; shift 2
  if timeout 60 "$@" >"$work/fail.log" 2>&1; then fail "$what: exited 0"; cat "$work/fail.log"; return; fi
  grep -q -- "$msg" "$work/fail.log" && ok "$what: refused ($msg)" || { fail "$what: no '$msg'"; cat "$work/fail.log"; }
}
expect_fail "unknown mode" "mode 'walk': run or cosim" \
  "${slurm_env[@]}" bash "$script" walk tests/dem_service/scene.yaml
expect_fail "missing binaries" "/nonexistent/dem_run" \
  "${slurm_env[@]}" SOILCOSIM_BIN=/nonexistent bash "$script" run tests/dem_service/scene.yaml
sed 's|"\$bin/dem_run" "\$config"|"$bin/dem_run" "$config" --no-such-option|' "$script" >"$work/broken.sbatch"
grep -q -- "--no-such-option" "$work/broken.sbatch" || fail "could not plant a bad option in a copy of the script"
expect_fail "an option dem_run does not know" "unknown or incomplete option '--no-such-option'" \
  "${slurm_env[@]}" bash "$work/broken.sbatch" run tests/dem_service/scene.yaml --set run.duration=0.001
sed 's|--report-bindings|--report-bindings --no-such-mpirun-option|' "$script" >"$work/broken2.sbatch"
grep -q -- "--no-such-mpirun-option" "$work/broken2.sbatch" || fail "could not plant a bad mpirun option in a copy"
expect_fail "an option mpirun does not know" "no-such-mpirun-option" \
  "${slurm_env[@]}" bash "$work/broken2.sbatch" run tests/dem_service/scene.yaml --set run.duration=0.001

[ "$fails" -eq 0 ] || { echo "mpi_slurm_script_test: $fails check(s) failed"; exit 1; }
echo "mpi_slurm_script_test: all checks passed"
