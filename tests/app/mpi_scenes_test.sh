#!/usr/bin/env bash
# The shipped piles under MPI (docs/reliability.md, "Rank and thread independence of the
# shipped scenes"): inputs/tori200.yaml and inputs/chess500.yaml, 200 steps through
# contact on 1, 2, 3 and 4 ranks with 1 and 2 OpenMP threads each, every frame (steps
# 0/50/100/150/200 of the 200) bitwise equal to 1 rank and 1 thread (all datasets but
# owner_rank, tests/app/check_output.py), and the diagnostics rows (energies, momentum,
# contacts) equal as text. tori200 runs with 'mutual_pairs: true' (docs/collision.md,
# "Penetration vectors", item 7: 1,618 records settled in steps 1000 to 1200; on 2 ranks
# 24,538 record keys cross to the other rank for it in those steps) and
# 'contact_closure: coupled' (docs/contact.md, "Coupled closure": every rank's rows
# gathered on rank 0, solved there, the magnitudes sent back); chess500 with the
# shipped (local) closure. Its chains first touch at step
# 366, so its 200 steps continue a checkpoint written at step 1000 by a 1-rank run; chess500's first contact is at
# step 28, so it runs from the start. The colliding-point counts of diagnostics.csv are
# asserted > 0 at every frame after the first contact, so the runs do exercise contact.
# Then two small scenes with edge and self-contact records (see below).
# Usage: mpi_scenes_test.sh EXE MPIEXEC INPUTS_DIR WORK
set -u
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
exe=$1 mpiexec=$2 inputs=$3 work=$4
rm -rf "$work" && mkdir -p "$work" && cd "$work" || exit 1
source "$here/expect.sh"   # ok, bad, expect
check="/usr/bin/python3 $here/check_output.py"

# tori200 from step 1000: a checkpoint of a 1-rank run (the restart itself is tested
# elsewhere; here it only puts the start inside the contact phase).
sed 's/^simulation:/simulation:\n  mutual_pairs: true\n  contact_closure: coupled/' "$inputs/tori200.yaml" > tori_mutual.yaml
grep -q '^  mutual_pairs: true' tori_mutual.yaml && ok || bad "tori_mutual.yaml: mutual_pairs not set"
grep -q '^  contact_closure: coupled' tori_mutual.yaml && ok || bad "tori_mutual.yaml: contact_closure not set"
expect 0 'done: 1000 steps' -- "$exe" run tori_mutual.yaml --steps 1000 --checkpoint-every 1000 \
  --output-every 1000 --output tori_start --quiet
ckpt=tori_start/checkpoints/checkpoint_000000001000.h5
[ -s "$ckpt" ] && ok || bad "no checkpoint at step 1000 in tori_start"

# run NAME RANKS THREADS: one run of scene NAME into NAME_rRANKS_tTHREADS.
run() {
  local name=$1 np=$2 nt=$3 dir=$1_r$2_t$3
  local args=("$inputs/chess500.yaml" --steps 200)
  [ "$name" = tori ] && args=(--restart "$ckpt" --steps 1200)
  expect 0 "on $np rank\(s\) x $nt thread\(s\)" -- "$mpiexec" --oversubscribe --bind-to none -n "$np" \
    env OMP_NUM_THREADS="$nt" "$exe" run "${args[@]}" --output-every 50 --output "$dir" --quiet
}

# colliding points > 0 in every diagnostics row after step AFTER (column 'contacts'), and
# at least 4 such rows
contacts_after() {
  awk -F, -v after="$2" 'NR == 1 { for (i = 1; i <= NF; ++i) if ($i == "contacts") c = i; next }
    $1 > after { n++; if ($c + 0 <= 0) z++ } END { exit !(c && n >= 4 && !z) }' "$1/diagnostics.csv"
}

for name in tori chess; do
  run "$name" 1 1
  ref=${name}_r1_t1
  # after the restart's step 1000 (its first row, written before any step, counts none),
  # or chess500's first contact at step 28
  after=1000; [ "$name" = chess ] && after=28
  contacts_after "$ref" "$after" && ok ||
    bad "$ref: a diagnostics row after step $after has no colliding point: $(cut -d, -f1,9 "$ref/diagnostics.csv" | tr '\n' ' ')"
  for np in 1 2 3 4; do
    for nt in 1 2; do
      [ "$np$nt" = 11 ] && continue
      run "$name" "$np" "$nt"
      dir=${name}_r${np}_t${nt}
      out=$($check "$dir" "$ref" --min-frames 5 --same-count 2>&1) && ok || bad "$dir: $out"
      # The physics columns (step to edge_contacts; the timings differ) as text.
      if cmp -s <(cut -d, -f1-13 "$dir/diagnostics.csv") <(cut -d, -f1-13 "$ref/diagnostics.csv"); then ok; else
        bad "$dir/diagnostics.csv differs from $ref:"; diff <(cut -d, -f1-13 "$dir/diagnostics.csv") <(cut -d, -f1-13 "$ref/diagnostics.csv") | head -6
      fi
    done
  done
done

# The two small scenes of issue 15 whose records cross ranks: aligned_stack.yaml (edge
# records of docs/collision.md "Edge contacts", items 4, 6 and 7, between the
# two boxes) and ring_squeeze.yaml with edge contacts on as well (vertex and edge
# self-contact records), whole, on 2 and 3 ranks with 1 and 2 threads, bitwise equal to 1
# rank and 1 thread. Each must have edge records (diagnostics column edge_contacts) in
# some row.
scenes=$here/../data/scenes
sed 's/^  self_collisions: true/  self_collisions: true\n  edge_contacts: true/' "$scenes/ring_squeeze.yaml" > ring_edges.yaml
grep -q '^  edge_contacts: true' ring_edges.yaml && ok || bad "ring_edges.yaml: edge_contacts not set"
# ring_squeeze.yaml as it is (vertex records only) too: its ring holds 720 of the 864 tets,
# so on 2 and 3 ranks it is split for its forces, and its points inside its own body are
# found with the detection of a split object (docs/architecture.md, "Contact of a split
# object"; delegated to the owner of the body, which is the ring's own).
for scene in "$scenes/aligned_stack.yaml" ring_edges.yaml "$scenes/ring_squeeze.yaml"; do
  name=$(basename "$scene" .yaml)
  for np in 1 2 3; do
    for nt in 1 2; do
      [ "$np$nt" = 12 ] && continue
      dir=${name}_r${np}_t${nt}
      pattern="on $np rank\(s\) x $nt thread\(s\)"
      [ "$name" != aligned_stack ] && [ "$np" -gt 1 ] && pattern="1 object\(s\) split for their forces over $np ranks"
      expect 0 "$pattern" -- "$mpiexec" --oversubscribe --bind-to none -n "$np" \
        env OMP_NUM_THREADS="$nt" "$exe" run "$scene" --output-every 100 --output "$dir" --quiet
      if [ "$np$nt" = 11 ]; then
        [ "$name" = ring_squeeze ] && continue  # vertex records only (its self-contact: cli.self_contact.ring_squeeze)
        awk -F, 'NR == 1 { for (i = 1; i <= NF; ++i) if ($i == "edge_contacts") c = i; next }
          $c + 0 > 0 { n++ } END { exit !(c && n > 0) }' "$dir/diagnostics.csv" && ok ||
          bad "$dir: no edge records in any diagnostics row"
        continue
      fi
      ref=${name}_r1_t1
      out=$($check "$dir" "$ref" --min-frames 5 --same-count 2>&1) && ok || bad "$dir: $out"
      cmp -s <(cut -d, -f1-13 "$dir/diagnostics.csv") <(cut -d, -f1-13 "$ref/diagnostics.csv") && ok ||
        bad "$dir/diagnostics.csv differs from $ref"
    done
  done
done

# inputs/soft_floor.yaml: its floor holds half of the tets, so on 2 to 4 ranks its forces
# are shared by every rank (docs/architecture.md, "Objects split for their
# forces"; on 2 ranks it is just under a share: not split). 400 steps (the lower balls land at step 125, the boxes from about step
# 340) on 2, 3 and 4 ranks with 1 thread and on 4 ranks with 2, and on 4
# ranks with the splitting off: every frame bitwise the 1-rank run's, and the run's summary
# must say that the floor was split over every rank.
sed 's/^  integrator: verlet/  integrator: verlet\n  split_objects: false/' "$inputs/soft_floor.yaml" > soft_floor_whole.yaml
grep -q '^  split_objects: false' soft_floor_whole.yaml && ok || bad "soft_floor_whole.yaml: split_objects not set"
for v in 1_1 2_1 3_1 4_1 4_2 whole_4_1; do
  np=${v%_*}; np=${np#whole_}; nt=${v##*_}; scene=$inputs/soft_floor.yaml; pattern="split for their forces over $np ranks"
  [ "$np" = 1 ] && pattern="on 1 rank"
  # 80,736 of 161,760 tets: on 2 ranks the floor is not larger than a share, not split
  [ "$np" = 2 ] && pattern="repartitions$"
  case $v in whole_*) scene=soft_floor_whole.yaml; pattern="repartitions$" ;; esac
  dir=soft_floor_$v
  expect 0 "$pattern" -- "$mpiexec" --oversubscribe --bind-to none -n "$np" \
    env OMP_NUM_THREADS="$nt" "$exe" run "$scene" --steps 400 --output-every 100 --output "$dir" --quiet
  [ "$v" = 1_1 ] && continue
  out=$($check "$dir" soft_floor_1_1 --min-frames 5 --same-count 2>&1) && ok || bad "$dir: $out"
  cmp -s <(cut -d, -f1-13 "$dir/diagnostics.csv") <(cut -d, -f1-13 soft_floor_1_1/diagnostics.csv) && ok ||
    bad "$dir/diagnostics.csv differs from soft_floor_1_1"
done

echo "mpi scenes: $passes passed, $fails failed"
[ "$fails" = 0 ]
