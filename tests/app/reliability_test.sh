#!/usr/bin/env bash
# Reliability of a run (docs/reliability.md): kill -9 at several moments leaves frames
# that h5py and the XDMF can read and a checkpoint from which the run continues to the
# same result as an uninterrupted one; SIGTERM (one rank, and two ranks under mpiexec)
# writes a checkpoint and ends the run cleanly; a numerical failure exits with status 3.
# Usage: reliability_test.sh EXE MPIEXEC DATA WORK
set -u
exe=$1 mpiexec=$2 data=$3 work=$4
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
check="/usr/bin/python3 $here/check_output.py"
rm -rf "$work" && mkdir -p "$work" && cd "$work" || exit 1
fails=0
bad() { echo "FAIL: $*"; fails=$((fails + 1)); }
scene=$data/scenes/pile.yaml
args=(--steps 3000 --output-every 10 --checkpoint-every 100 --quiet)

# The reference: uninterrupted.
"$exe" run "$scene" "${args[@]}" --output ref > ref.log 2>&1 || { bad "reference run failed"; cat ref.log; }

# kill -9 at moments spread over the run (which takes a few seconds).
for delay in 0.3 0.7 1.1 1.5 2.0; do
  rm -rf k
  "$exe" run "$scene" "${args[@]}" --output k > k.log 2>&1 &
  pid=$!
  sleep "$delay"
  kill -9 "$pid" 2>/dev/null
  wait "$pid" 2>/dev/null
  if [ ! -f k/frames.h5 ]; then echo "kill after ${delay} s: before the first frame"; continue; fi
  $check k --min-frames 1 || bad "output unreadable after kill -9 at ${delay} s"
  if ls k/checkpoints/checkpoint_*.h5 > /dev/null 2>&1; then
    "$exe" run --restart k --quiet > r.log 2>&1 || { bad "restart after kill -9 at ${delay} s failed"; cat r.log; }
    grep -q "restart: from" r.log || bad "restart did not say where it continues from"
    $check k ref --same-count || bad "restart after kill -9 at ${delay} s differs from the uninterrupted run"
  else
    echo "kill after ${delay} s: before the first checkpoint"
  fi
done

# SIGTERM, one rank: a checkpoint, exit status 0, a message; then continue to the end.
rm -rf t1
"$exe" run "$scene" --steps 200000 --output-every 10 --quiet --output t1 > t1.log 2>&1 &
pid=$!
sleep 2
kill -TERM "$pid"
wait "$pid"
rc=$?
[ "$rc" = 0 ] || bad "SIGTERM: exit status $rc, expected 0"
grep -q "stopped by SIGTERM at step" t1.log || { bad "SIGTERM: no message"; cat t1.log; }
ckpt=$(sed -n 's/^continue with: softcontact run --restart //p' t1.log)
[ -f "$ckpt" ] || bad "SIGTERM: the checkpoint '$ckpt' named in the message does not exist"
$check t1 --min-frames 2 || bad "SIGTERM: output unreadable"
step=$(sed -n 's/.*stopped by SIGTERM at step \([0-9]*\).*/\1/p' t1.log)
if [ -n "$step" ]; then
  "$exe" run --restart t1 --steps $((step + 300)) --quiet > t1r.log 2>&1 || { bad "SIGTERM: restart failed"; cat t1r.log; }
  "$exe" run "$scene" --steps $((step + 300)) --output-every 10 --quiet --output t1ref > /dev/null 2>&1
  $check t1 t1ref --same-count || bad "SIGTERM: the continued run differs from an uninterrupted one"
fi

# SIGTERM to mpiexec with two ranks: it forwards the signal; both ranks finish the step
# and write one checkpoint together.
rm -rf t2
"$mpiexec" --oversubscribe -n 2 "$exe" run "$scene" --steps 200000 --output-every 10 --quiet --output t2 > t2.log 2>&1 &
pid=$!
sleep 4
kill -TERM "$pid"
wait "$pid"
grep -q "stopped by SIGTERM at step" t2.log || { bad "SIGTERM (2 ranks): no message"; cat t2.log; }
ls t2/checkpoints/checkpoint_*.h5 > /dev/null 2>&1 || bad "SIGTERM (2 ranks): no checkpoint"
$check t2 --min-frames 1 || bad "SIGTERM (2 ranks): output unreadable"

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
"$exe" run unstable.yaml --output u --quiet > u.log 2>&1
rc=$?
[ "$rc" = 3 ] || bad "numerical failure: exit status $rc, expected 3"
grep -q "numerical failure at step .* of object 'block'" u.log || { bad "numerical failure: message"; cat u.log; }
grep -qE 'Segmentation|terminate called|PETSC ERROR' u.log && bad "numerical failure: crashed"

if [ "$fails" -gt 0 ]; then echo "$fails failure(s)"; exit 1; fi
echo "all reliability checks passed"
