#!/usr/bin/env bash
# Reliability of a run (docs/reliability.md), with faults injected at chosen steps and
# points through SOFTCONTACT_FAULT (no sleeps decide anything, and no check is skipped):
#  - kill -9 during a frame write, before and after its rename, during a checkpoint write,
#    before and after its rename, on one rank and under mpiexec with two: the frames
#    written before open in h5py and the XDMF, the newest complete checkpoint (the one
#    expected, or the test fails) continues the run on another rank count to the frames
#    of an uninterrupted run, bitwise;
#  - SIGINT and SIGTERM (one rank; one rank of two; SIGTERM to every rank of an mpiexec job): a
#    checkpoint at the step, exit status 0, a message; the restart is bitwise;
#  - --checkpoint-minutes writes checkpoints by wall time; --restart CKPT --output NEWDIR
#    continues into a new directory; a checkpoint whose scene reads differently now is
#    refused (exit 2, one message);
#  - one rank of three fails (non-finite position: exit 3; I/O error: exit 1), or the
#    output directory cannot be created: the whole job ends, one message, no hang;
#  - a numerical failure on one rank exits with status 3 and the place.
# Usage: reliability_test.sh EXE MPIEXEC DATA WORK
set -u
exe=$1 mpiexec=$2 data=$3 work=$4
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
check="/usr/bin/python3 $here/check_output.py"
rm -rf "$work" && mkdir -p "$work" && cd "$work" || exit 1
source "$here/expect.sh"
scene=$data/scenes/pile.yaml
# 200 steps, a frame every 10 (21 frames), a checkpoint every 50 (two kept).
args=(--steps 200 --output-every 10 --checkpoint-every 50 --quiet)
# RANKS command...: under mpiexec, with a 60 s hang guard; one rank runs directly.
mpi() {
  local n=$1; shift
  if [ "$n" = 1 ]; then timeout 60 "$@"; else timeout 60 "$mpiexec" --oversubscribe -n "$n" "$@"; fi
}
ckpt() { printf '%s/checkpoints/checkpoint_%012d.h5' "$1" "$2"; }
# The number of lines softcontact printed as errors (one per failure, not one per rank).
errors() { grep -c '^softcontact: error' "$1"; }

# The reference: uninterrupted, one rank.
"$exe" run "$scene" "${args[@]}" --output ref > ref.log 2>&1 || { bad "reference run failed"; cat ref.log; }
$check ref --min-frames 21 > /dev/null || bad "reference output unreadable"

# kill -9 at POINT of STEP on RANKS rank(s) (rank RANK, or all); then the output must be
# readable with at least FRAMES frames, the newest checkpoint must be the one at step
# CKPT, and the run continued from its directory on AGAIN ranks must equal the reference.
kill_case() {
  local ranks=$1 fault=$2 frames=$3 ck=$4 again=$5
  local name="kill -9 at ${fault} on ${ranks} rank(s)" d="k_${fault//:/_}_$ranks"
  rm -rf "$d"
  SOFTCONTACT_FAULT=$fault mpi "$ranks" "$exe" run "$scene" "${args[@]}" --output "$d" > "$d.log" 2>&1
  local rc=$?
  # One rank: killed by SIGKILL (128 + 9). mpiexec: reports the killed rank and fails.
  if [ "$ranks" = 1 ] && [ "$rc" != 137 ]; then bad "$name: exit status $rc, expected 137 (SIGKILL)"; fi
  if [ "$ranks" != 1 ] && { [ "$rc" = 0 ] || [ "$rc" = 124 ]; }; then bad "$name: mpiexec exit status $rc"; fi
  grep -q "injecting kill at $(cut -d: -f2 <<<"$fault"), step $(cut -d: -f3 <<<"$fault")" "$d.log" ||
    { bad "$name: the fault did not fire"; cat "$d.log"; return; }
  $check "$d" --min-frames "$frames" > /dev/null || bad "$name: output unreadable"
  local newest
  newest=$(ls "$d"/checkpoints/checkpoint_*.h5 2>/dev/null | tail -1)
  [ "$newest" = "$(ckpt "$d" "$ck")" ] || { bad "$name: newest checkpoint '$newest', expected step $ck"; return; }
  mpi "$again" "$exe" run --restart "$d" --quiet > "$d.r.log" 2>&1 || { bad "$name: restart on $again rank(s) failed"; cat "$d.r.log"; return; }
  grep -q "restart: from $(ckpt "$d" "$ck") (step $ck, written on $ranks rank(s))" "$d.r.log" ||
    { bad "$name: the restart did not say it continues from step $ck"; cat "$d.r.log"; }
  $check "$d" ref --same-count > /dev/null || bad "$name: continued on $again rank(s), differs from the uninterrupted run"
  ls "$d"/frames/*.tmp > /dev/null 2>&1 && bad "$name: temporary frame files left after the restart"
  ok
}
kill_case 1 kill:frame_write:120 12 100 2        # frame 12 half written
kill_case 1 kill:frame_rename:120 12 100 1       # frame 12 complete, not renamed
kill_case 1 kill:frame_renamed:120 12 100 3      # frame 12 renamed, not yet in the index
kill_case 1 kill:checkpoint_write:150 15 100 2   # checkpoint 150 half written
kill_case 1 kill:checkpoint_rename:150 15 100 1  # checkpoint 150 complete, not renamed
kill_case 1 kill:checkpoint_renamed:150 15 150 2 # checkpoint 150 renamed, 50 not yet pruned
kill_case 2 kill:frame_write:120 12 100 3        # both ranks inside the parallel frame write
kill_case 2 kill:checkpoint_rename:150:0 15 100 1  # rank 0 about to rename the checkpoint

# A stop signal raised at step 77 on one rank (SIGINT), on rank 1 of 2 (SIGTERM): both
# ranks stop after step 77 with a checkpoint, exit 0 and say how to continue.
signal_case() {
  local ranks=$1 fault=$2 sig=$3 again=$4
  local name="$sig on ${ranks} rank(s)" d="s_${sig}_$ranks"
  rm -rf "$d"
  SOFTCONTACT_FAULT=$fault mpi "$ranks" "$exe" run "$scene" "${args[@]}" --output "$d" > "$d.log" 2>&1
  local rc=$?
  [ "$rc" = 0 ] || { bad "$name: exit status $rc, expected 0"; cat "$d.log"; }
  grep -q "stopped by $sig at step 77" "$d.log" || { bad "$name: no message"; cat "$d.log"; return; }
  grep -q "^continue with: softcontact run --restart .*/$(ckpt "$d" 77)$" "$d.log" || bad "$name: no checkpoint named"
  [ -f "$(ckpt "$d" 77)" ] || { bad "$name: no checkpoint at step 77"; return; }
  $check "$d" --min-frames 8 > /dev/null || bad "$name: output unreadable"
  mpi "$again" "$exe" run --restart "$(ckpt "$d" 77)" --quiet > "$d.r.log" 2>&1 || { bad "$name: restart failed"; cat "$d.r.log"; }
  $check "$d" ref --same-count > /dev/null || bad "$name: the continued run differs from the uninterrupted one"
  ok
}
signal_case 1 sigint:step:77 SIGINT 2
signal_case 2 sigterm:step:77:1 SIGTERM 3

# SIGTERM sent to every rank of an mpiexec job at once, as Slurm does at the end of a
# job's time (scancel, time limit): waits (up to 60 s) for the fourth frame, then
# signals; where the run stops does not matter, only that it does, with a checkpoint from
# which it continues bitwise. (SIGTERM to mpiexec itself is not tested: Open MPI 4.1
# forwards it late and follows it with SIGKILL after odls_base_sigkill_timeout, 1 s by
# default, so whether the ranks checkpoint depends on load; docs/reliability.md, "Signals".)
rm -rf t2
timeout 60 "$mpiexec" --oversubscribe -n 2 "$exe" run "$scene" --steps 200000 --output-every 10 --quiet --output t2 > t2.log 2>&1 &
pid=$!
for _ in $(seq 600); do [ -f t2/frames/000003.h5 ] && break; sleep 0.1; done
for p in $(pgrep -f -- "--output t2\$"); do
  [ "$(cat "/proc/$p/comm" 2>/dev/null)" = softcontact ] && kill -TERM "$p"
done
wait "$pid"
step=$(sed -n 's/.*stopped by SIGTERM at step \([0-9]*\).*/\1/p' t2.log)
if [ -z "$step" ]; then
  bad "SIGTERM to every rank: no message"; cat t2.log
else
  [ -f "$(ckpt t2 "$step")" ] || bad "SIGTERM to every rank: no checkpoint at step $step"
  $check t2 --min-frames 4 > /dev/null || bad "SIGTERM to every rank: output unreadable"
  mpi 1 "$exe" run --restart t2 --steps $((step + 55)) --quiet > t2r.log 2>&1 || { bad "SIGTERM to every rank: restart failed"; cat t2r.log; }
  "$exe" run "$scene" --steps $((step + 55)) --output-every 10 --quiet --output t2ref > /dev/null 2>&1
  $check t2 t2ref --same-count > /dev/null || bad "SIGTERM to every rank: the continued run differs from an uninterrupted one"
  ok
fi

# --checkpoint-minutes: with 1e-9 min (60 ns) every step is due, so step 59 of 60 has a
# checkpoint written by wall time alone (the last step's one is written anyway).
rm -rf cm
"$exe" run "$scene" --steps 60 --output-every 10 --checkpoint-minutes 1e-9 --quiet --output cm > cm.log 2>&1 ||
  { bad "--checkpoint-minutes: run failed"; cat cm.log; }
if [ -f "$(ckpt cm 59)" ]; then
  mpi 2 "$exe" run --restart "$(ckpt cm 59)" --steps 200 --quiet > cm.r.log 2>&1 || { bad "--checkpoint-minutes: restart failed"; cat cm.r.log; }
  $check cm ref --same-count > /dev/null || bad "--checkpoint-minutes: the continued run differs from the uninterrupted one"
  ok
else
  bad "--checkpoint-minutes: no checkpoint at step 59"; ls cm/checkpoints
fi

# --restart CKPT --output NEWDIR: continues from the reference's step-150 checkpoint into
# a new directory (two ranks), frames from step 150 on equal to the reference's; the
# reference directory is left as it was.
rm -rf nd
mpi 2 "$exe" run --restart "$(ckpt ref 150)" --output nd --quiet > nd.log 2>&1 || { bad "--output NEWDIR: restart failed"; cat nd.log; }
$check nd ref --by-step --min-frames 6 > /dev/null || bad "--output NEWDIR: frames differ from the uninterrupted run"
$check ref --min-frames 21 > /dev/null && [ -f "$(ckpt ref 200)" ] || bad "--output NEWDIR: the old directory changed"
ok

# A checkpoint whose scene now reads differently (its mesh file changed) is refused: exit
# 2, one message naming the checkpoint, on two ranks.
cp "$data/meshes/cube_v22.msh" cube.msh
cat > cube.yaml <<'YAML'
simulation: {dt: auto, steps: 20, output: {every: 10}, checkpoint: {every: 10}}
materials:
  - {name: soft, model: corotational, young: 1.0e5, poisson: 0.3, density: 1000}
  - {name: ground, model: linear, young: 1.0e7, poisson: 0.3, density: 2000}
objects:
  - {name: floor, material: ground, kinematic: true, transform: {translate: [0, 0, -0.05]},
     primitive: {type: plate, size: [3, 3], thickness: 0.1, cells: [2, 2]}}
  - {name: cube, material: soft, mesh: cube.msh, transform: {translate: [-0.5, -0.5, 0.01]}}
YAML
rm -rf fp
"$exe" run cube.yaml --output fp --quiet > fp.log 2>&1 || { bad "fingerprint: run failed"; cat fp.log; }
sed -i 's/^7 1 1 1$/7 1 1 1.01/' cube.msh
expect 2 "$(ckpt fp 20): the scene it continues .* now reads differently" -- mpi 2 "$exe" run --restart fp --quiet
mpi 2 "$exe" run --restart fp --quiet > fp.r.log 2>&1
[ "$(errors fp.r.log)" = 1 ] || { bad "fingerprint: $(errors fp.r.log) error messages, expected 1"; cat fp.r.log; }

# One rank of three fails, all stop: the job's exit status, one error message, within the
# 60 s hang guard (timeout's status 124 would say it hung).
one_fails() {
  local name=$1 code=$2 pattern=$3 d=$4
  shift 4
  rm -rf "$d"
  "$@" > "$d.log" 2>&1
  local rc=$?
  [ "$rc" = "$code" ] || { bad "$name: exit status $rc, expected $code"; cat "$d.log"; return; }
  [ "$(errors "$d.log")" = 1 ] || { bad "$name: $(errors "$d.log") error messages, expected 1"; cat "$d.log"; return; }
  grep -qE -- "$pattern" "$d.log" || { bad "$name: message lacks /$pattern/"; cat "$d.log"; return; }
  grep -qE 'terminate called|Segmentation|core dumped|HDF5-DIAG' "$d.log" && { bad "$name: crashed"; cat "$d.log"; return; }
  ok
}
one_fails "non-finite position on rank 1 of 3" 3 \
  "^softcontact: error: numerical failure at step 57 .*non-finite position" f_nan \
  env SOFTCONTACT_FAULT=nan:step:57:1 timeout 60 "$mpiexec" --oversubscribe -n 3 "$exe" run "$scene" "${args[@]}" --output f_nan
one_fails "I/O error on rank 2 of 3 in a frame write" 1 \
  "^softcontact: error on rank 2: cannot write 'f_io/frames/000006.h5.tmp': Input/output error" f_io \
  env SOFTCONTACT_FAULT=ioerror:frame_write:60:2 timeout 60 "$mpiexec" --oversubscribe -n 3 "$exe" run "$scene" "${args[@]}" --output f_io
one_fails "I/O error on rank 1 of 3 in a checkpoint write" 1 \
  "^softcontact: error on rank 1: cannot write .*checkpoint_000000000100.h5.tmp': Input/output error" f_ck \
  env SOFTCONTACT_FAULT=ioerror:checkpoint_write:100:1 timeout 60 "$mpiexec" --oversubscribe -n 3 "$exe" run "$scene" "${args[@]}" --output f_ck
touch a_file
one_fails "output directory that cannot be created, 3 ranks" 1 \
  "^softcontact: error: cannot create the output directory 'a_file/out'" f_dir \
  timeout 60 "$mpiexec" --oversubscribe -n 3 "$exe" run "$scene" "${args[@]}" --output a_file/out

# A bad SOFTCONTACT_FAULT: exit status 2, a message saying what was expected.
expect 2 "SOFTCONTACT_FAULT='nan:frame_write:5': 'nan' applies at the point 'step' only" -- \
  env SOFTCONTACT_FAULT=nan:frame_write:5 "$exe" run "$scene" --quiet --output bf
expect 2 "SOFTCONTACT_FAULT='kill:step:5:3': rank 3, but the job has 2 rank\(s\)" -- \
  env SOFTCONTACT_FAULT=kill:step:5:3 timeout 60 "$mpiexec" --oversubscribe -n 2 "$exe" run "$scene" --quiet --output bf

# A numerical failure: exit status 3 and the place.
cat > unstable.yaml <<'YAML'
simulation:
  dt: 0.004
  steps: 400
  output: {every: 1000}
materials:
  - {name: soft, model: corotational, young: 1.0e5, poisson: 0.3, density: 1000}
  - {name: ground, model: linear, young: 1.0e7, poisson: 0.3, density: 2000}
objects:
  - {name: floor, material: ground, kinematic: true, transform: {translate: [0, 0, -0.05]},
     primitive: {type: plate, size: [1, 1], thickness: 0.1, cells: [4, 4]}}
  - {name: block, material: soft, transform: {translate: [0, 0, 0.1005]},
     primitive: {type: box, size: [0.2, 0.2, 0.2], cells: [3, 3, 3]}}
YAML
expect 3 "numerical failure at step .* of object 'block'" -- "$exe" run unstable.yaml --output u --quiet

if [ "$fails" -gt 0 ]; then echo "$fails failure(s), $passes passed"; exit 1; fi
echo "all $passes reliability checks passed"
