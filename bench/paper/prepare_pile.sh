#!/usr/bin/env bash
# Prepares the paper-sized pile in two stages. Stage 1 fills the bay closed by a temporary front
# wall:
#   default:     a granular packing (issue 43): random insertion and deposition with friction
#                0.116, frozen with the paper's law (configs/soil/pile_paper_deposit.yaml ->
#                results/pile_paper_bed.h5; prints its packing fraction, bulk density and
#                coordination: 0.616, 1,603 kg/m^3, 5.45). Stage 2 -> results/pile_paper.h5,
#                the pile of configs/wheel_loader_paper.yaml (at rest after 5.27 s of
#                pile_paper_prepare.yaml's 8).
#   --compact:   the pile before issue 43, a frictionless dense drop from a lattice
#                (configs/soil/pile_paper_compact.yaml -> results/pile_paper_compact.h5; packing
#                0.646, 6.0 contacts per grain). Stage 2 -> results/pile_paper_compacted.h5, the
#                pile of configs/wheel_loader_paper_compact.yaml (at rest after 0.97 s).
#   --granular:  the default, accepted for the commands written before it was.
# Stage 1 is skipped when its file exists. Stage 2 (configs/soil/pile_paper_prepare.yaml) turns
# friction on, opens the front and settles until at rest. Fails if stage 2 does not reach its
# rest criterion. Further arguments are `--set key=value` overrides passed to stage 2. Times on
# the shared 2-core host (docs/soil.md, "Prepared piles"): granular about 30 + 35 minutes,
# compaction about 4 + 2-4 minutes.
#   nice -n 19 bash bench/paper/prepare_pile.sh [--compact] [--set key=value ...]
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
cd "$root"
build="${BUILD_DIR:-build}"
stage1=deposit
stage2_sets=()
while [ $# -gt 0 ]; do
  case "$1" in
    --granular) stage1=deposit; shift ;;
    --compact) stage1=compact; shift ;;
    --set)
      if [ $# -lt 2 ] || [[ "$2" != *=* ]]; then
        echo "prepare_pile: --set needs key=value (e.g. --set settle.max_time=10)" >&2; exit 2
      fi
      stage2_sets+=(--set "$2"); shift 2 ;;
    *) echo "prepare_pile: unknown argument '$1' (--compact: the frictionless compaction of before issue 43; --granular: random insertion and deposition, the default; --set key=value: a stage-2 override)" >&2; exit 2 ;;
  esac
done
mkdir -p results
if [ "$stage1" = compact ]; then
  bed=results/pile_paper_compact.h5
  pile=results/pile_paper_compacted.h5
  stem=pile_paper_compacted_prepare
else
  bed=results/pile_paper_bed.h5
  pile=results/pile_paper.h5
  stem=pile_paper_prepare
fi
if [ ! -f "$bed" ]; then
  "$build/bin/dem_run" "configs/soil/pile_paper_$stage1.yaml" 2>&1 | tee "results/pile_paper_$stage1.log"
fi
"$build/bin/dem_run" configs/soil/pile_paper_prepare.yaml --set "particles.checkpoint=../../$bed" \
  --set "settle.checkpoint=$pile" --set "output.file=results/$stem.h5" \
  ${stage2_sets[@]+"${stage2_sets[@]}"} 2>&1 \
  | tee "results/$stem.log"
if ! grep -q "^settle: at rest" "results/$stem.log"; then
  unsettled="${pile%.h5}_unsettled.h5"
  echo "prepare_pile: the pile did NOT reach its rest criterion; see results/$stem.log" >&2
  echo "prepare_pile: its last state kept as $unsettled (not for the scene)" >&2
  if [ -f "$pile" ]; then mv -f "$pile" "$unsettled"; fi
  exit 3
fi
