#!/usr/bin/env bash
# The main job: set up (install, build), then run a scene under mpirun on all cores.
# Usage: bash tools/run.sh [SCENE.yaml] [softcontact run options]
#   default scene inputs/default.yaml, written to output/default. With no run options the
#   output directory (the scene's output.directory) is replaced on re-runs (--overwrite);
#   give options to control it yourself.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
bash "$root/tools/setup.sh"
cores=$(OMP_NUM_THREADS= nproc)   # nproc obeys OMP_NUM_THREADS, which env.sh sets
source "$root/tools/env.sh"
scene=${1:-$root/inputs/default.yaml}
[ $# -gt 0 ] && shift
args=("$@")
if [ $# -eq 0 ]; then
  args=(--overwrite)
  if [ "$scene" = "$root/inputs/default.yaml" ]; then args=(--output output/default --overwrite); fi
fi
# Until contacts can cross ranks (halo exchange), one rank with one OpenMP thread per
# core is the fastest correct layout; RANKS and OMP_NUM_THREADS override it.
ranks=${RANKS:-1}
export OMP_NUM_THREADS=${SOFTCONTACT_THREADS:-$cores}
echo "softcontact: mpirun -n $ranks build/bin/softcontact run $scene ${args[*]}  ($OMP_NUM_THREADS threads per rank)"
exec mpirun -n "$ranks" --bind-to none "$root/build/bin/softcontact" run "$scene" "${args[@]}"
