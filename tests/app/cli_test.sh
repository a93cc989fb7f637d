#!/usr/bin/env bash
# Command-line tests: exit codes, messages, outputs. Usage: cli_test.sh EXE MPIEXEC DATA WORK
set -u
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
exe=$1 mpiexec=$2 data=$3 work=$4
rm -rf "$work" && mkdir -p "$work" && cd "$work" || exit 1
source "$here/expect.sh"   # ok, bad, expect

expect 0 'run SCENE.yaml' -- "$exe" --help
expect 0 '--output-every K' -- "$exe" run --help
expect 0 '--overwrite' -- "$exe" run --help
expect 0 'validate' -- "$exe" check --help
expect 0 'PETSc' -- "$exe" info
expect 2 "unknown command 'rn' \(did you mean 'run'\?\)" -- "$exe" rn x.yaml
expect 2 'no command given' -- "$exe"
expect 2 "unknown option '--stpes' \(did you mean '--steps'\?\)" -- "$exe" run "$data/scenes/small.yaml" --stpes 3
expect 2 "--steps expects a positive integer, got '-3'" -- "$exe" run "$data/scenes/small.yaml" --steps=-3
expect 2 "--steps expects a positive integer, got 'ten'" -- "$exe" run "$data/scenes/small.yaml" --steps ten
expect 2 "missing.yaml: scene file does not exist" -- "$exe" run missing.yaml
expect 2 "give either a scene or --restart" -- "$exe" run "$data/scenes/small.yaml" --restart x.h5
expect 2 "nothing.h5: no such checkpoint file or directory" -- "$exe" run --restart nothing.h5
expect 2 "small.yaml: not a readable softcontact checkpoint" -- "$exe" run --restart "$data/scenes/small.yaml"
expect 2 "--checkpoint-every expects a positive integer, got '0'" -- "$exe" run "$data/scenes/small.yaml" --checkpoint-every 0
expect 0 '--restart FILE\|DIR' -- "$exe" run --help
expect 2 "bad_poisson.yaml:5: 'poisson' of material 'soft' must lie in \(-1, 0.5\)" -- "$exe" check "$data/scenes/bad_poisson.yaml"
expect 2 "typo.yaml:3: unknown key 'densty'.*did you mean 'density'" -- "$exe" run "$data/scenes/typo.yaml"
expect 2 "meshes/missing_node_v22.msh:19: element 3 refers to node 99" -- "$exe" run "$data/scenes/broken_mesh.yaml"
expect 2 "meshes/zero_tets_v22.msh: no 4-node tetrahedra" -- "$exe" run "$data/scenes/empty_mesh.yaml"
[ ! -e output ] && ok || bad "a failed run left an output directory"
# meshes from files: two Gmsh cubes (8 vertices, 6 tets each) and a TetGen cube
expect 0 'total: 24 vertices, 18 tets' -- "$exe" check "$data/scenes/with_mesh.yaml"

# check: a summary with the totals (2 cubes of 2x2x2 cells: 27 vertices, 48 tets each;
# floor 4x4x1 cells: 50 vertices, 96 tets)
expect 0 'total: 104 vertices, 192 tets' -- "$exe" check "$data/scenes/small.yaml"
expect 0 'stable explicit time step' -- "$exe" check "$data/scenes/small.yaml"
# check: which objects a run on N ranks splits for their forces (a floor of 52 % of the
# tets: from 2 ranks on; four cubes of 48 tets: each a quarter, more than a share from 5 ranks on)
expect 0 "split for their forces .*'floor' \(.* 52\.. % of the scene\) on 2 ranks" -- "$exe" check "$data/scenes/soft_floor.yaml" --ranks 2
expect 0 "split for their forces .*none on 1 rank\(s\); the largest deformable object, 'floor' .* would be from 2 ranks on" -- "$exe" check "$data/scenes/soft_floor.yaml"
expect 0 "split for their forces .*none on 3 rank\(s\); the largest deformable object, 'cube\[0\]' \(25\.0 % of the tets\), would be from 5 ranks on" -- "$exe" check "$data/scenes/small.yaml" --ranks 3
# check --ranks N: the partition a run on N ranks would make, by its static weights
# (4,096 equal boxes on 3 ranks: both imbalances within METIS's 1.03 of the mean).
expect 0 "partition on 3 ranks .*work imbalance 1\.0[0-2][0-9], memory imbalance 1\.0[0-2][0-9]" -- "$exe" check "$data/scenes/many_objects.yaml" --ranks 3
[ ! -e output ] && ok || bad "check wrote output"

# run: output files, frames at steps 0,5,10,15,20
expect 0 'output: +run1/frames.xdmf' -- "$exe" run "$data/scenes/small.yaml" --output run1 --quiet
for f in frames.h5 frames.xdmf diagnostics.csv scene.yaml; do [ -s run1/$f ] && ok || bad "run1/$f missing"; done
[ "$(grep -c '<Grid Name="frame_' run1/frames.xdmf)" = 5 ] && ok || bad "expected 5 frames in the XDMF"
[ "$(wc -l < run1/diagnostics.csv)" = 6 ] && ok || bad "expected a header and 5 rows in diagnostics.csv"
expect 2 "output directory 'run1' already exists; pass --overwrite" -- "$exe" run "$data/scenes/small.yaml" --output run1
expect 0 'done: 7 steps' -- "$exe" run "$data/scenes/small.yaml" --output run1 --overwrite --steps 7 --output-every 3
[ "$(grep -c '<Grid Name="frame_' run1/frames.xdmf)" = 4 ] && ok || bad "expected frames 0,3,6,7 after --overwrite"
expect 0 't = ' -- "$exe" run "$data/scenes/small.yaml" --output run2 --end-time 0.001

# bench: the table on stdout, one CSV row per run (appended, one header), one per-step
# row per timed step (numbered after the warm-up), no output directory; bad options exit 2
expect 0 '--per-step FILE' -- "$exe" bench --help
expect 0 'phase +median \[ms\] +mean \[ms\]' -- "$exe" bench "$data/scenes/small.yaml" --steps 3 --quiet
expect 0 'contact response' -- "$exe" bench "$data/scenes/small.yaml" --steps 3 --warmup 2 --csv b.csv --per-step steps.csv --quiet
expect 0 '3 timed steps' -- "$exe" bench "$data/scenes/small.yaml" --steps 3 --csv b.csv --quiet
[ "$(wc -l < b.csv)" = 3 ] && ok || bad "expected a header and 2 rows in b.csv"
[ "$(head -1 b.csv | cut -d, -f1-4)" = "timestamp,scene,path,ranks" ] && ok || bad "b.csv header: $(head -1 b.csv)"
[ "$(wc -l < steps.csv)" = 4 ] && ok || bad "expected a header and 3 rows in steps.csv"
[ "$(sed -n 2p steps.csv | cut -d, -f1)" = 3 ] && ok || bad "the first timed step after 2 warm-up steps should be step 3"
[ ! -e output ] && ok || bad "bench wrote an output directory"
expect 2 "--steps expects a positive integer, got '0'" -- "$exe" bench "$data/scenes/small.yaml" --steps 0
expect 2 "--warmup expects a non-negative integer, got '-1'" -- "$exe" bench "$data/scenes/small.yaml" --warmup -1
expect 2 "unknown option '--step' \(did you mean '--steps'\?\)" -- "$exe" bench "$data/scenes/small.yaml" --step 3
expect 2 "'bench' needs a scene file" -- "$exe" bench --steps 3
expect 2 "missing.yaml: scene file does not exist" -- "$exe" bench missing.yaml
expect 2 "--csv steps.csv: the file exists with other columns" -- "$exe" bench "$data/scenes/small.yaml" --csv steps.csv
expect 0 '2 rank\(s\) x 1 thread' -- "$mpiexec" --oversubscribe -n 2 "$exe" bench "$data/scenes/small.yaml" --steps 2 --quiet

# PETSc's -log_view (through PETSC_OPTIONS) reports the step's phases as events, one
# call per step: 3 steps, 3 calls of scContact
expect 0 'scContact +3 ' -- env PETSC_OPTIONS=-log_view "$exe" bench "$data/scenes/small.yaml" --steps 3 --quiet
expect 0 'scDetectDepth +3 ' -- env PETSC_OPTIONS=-log_view "$exe" bench "$data/scenes/small.yaml" --steps 3 --quiet

# under MPI: two ranks, the same output as one rank (run1 above: 7 steps, frames
# 0,3,6,7), every dataset of every frame bitwise but owner_rank (check_output.py reads
# them with h5py), and bad input still exits 2 with one message
expect 0 'on 2 rank' -- "$mpiexec" --oversubscribe -n 2 "$exe" run "$data/scenes/small.yaml" --output mpi2 --quiet \
  --steps 7 --output-every 3
out=$(/usr/bin/python3 "$here/check_output.py" mpi2 run1 --min-frames 4 --same-count 2>&1) && ok ||
  bad "2 ranks differ from 1 rank: $out"
expect 2 "typo.yaml:3: unknown key 'densty'" -- "$mpiexec" --oversubscribe -n 2 "$exe" run "$data/scenes/typo.yaml"
n=$("$mpiexec" --oversubscribe -n 2 "$exe" run "$data/scenes/typo.yaml" 2>&1 | grep -c "unknown key 'densty'")
[ "$n" = 1 ] && ok || bad "bad input under MPI printed the message $n times, expected once"

echo "cli: $passes passed, $fails failed"
[ "$fails" = 0 ]
