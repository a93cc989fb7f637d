#!/usr/bin/env bash
# softcontact verify and run --verify-every: exit codes, messages, the JSON files.
# Usage: verify_test.sh EXE MPIEXEC DATA WORK
set -u
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
exe=$1 mpiexec=$2 data=$3 work=$4
rm -rf "$work" && mkdir -p "$work" && cd "$work" || exit 1
source "$here/expect.sh"   # ok, bad, expect

expect 0 'verify OUTPUT_DIR' -- "$exe" --help
expect 0 '--max-depth F' -- "$exe" verify --help
expect 0 '--verify-every N' -- "$exe" run --help

# A run with contact (the cubes land at about step 85), checked every 10 steps in the run;
# verify_steps.json holds the maxima, the CSV its residual_penetration column.
expect 0 'verify \(every 10 steps, 26 checks\): deepest surface vertex' -- \
  "$exe" run "$data/scenes/small.yaml" --output run1 --steps 250 --output-every 25 --verify-every 10 --quiet
[ -s run1/verify_steps.json ] && ok || bad "run1/verify_steps.json missing"
grep -q '"surface_depth_edges": {"value": ' run1/verify_steps.json && ok || bad "verify_steps.json lacks the depth maximum"
head -1 run1/diagnostics.csv | grep -q residual_penetration && ok || bad "diagnostics.csv lost residual_penetration"
expect 2 "--verify-every expects a positive integer, got '0'" -- "$exe" run "$data/scenes/small.yaml" --verify-every 0

# verify: one line per frame (11 frames), a summary, PASS and verify.json with pass true
expect 0 'PASS: limits surface depth 0.005 h' -- "$exe" verify run1
[ "$(grep -cE '^ +[0-9]+ +[0-9]+ ' <<<"$("$exe" verify run1)")" = 11 ] && ok || bad "expected 11 frame lines"
grep -q '"pass": true' run1/verify.json && ok || bad "verify.json lacks pass: true"
grep -q '"max_depth_edges": 0.005' run1/verify.json && ok || bad "verify.json lacks the thresholds"
expect 0 'summary: 1 frame\(s\) checked' -- "$exe" verify run1 --frames last --json last.json
grep -q '"frame": 10' last.json && ok || bad "--frames last --json last.json: frame 10 missing"
expect 0 'summary: 4 frame\(s\) checked' -- "$exe" verify run1 --frames 0,2:6:2
expect 0 'summary: 2 frame\(s\) checked' -- "$exe" verify run1 --frames -2:-1
expect 0 'summary: 4 frame\(s\) checked' -- "$exe" verify run1 --skip-frames-before 0.55
expect 2 "--frames '12': there is no frame 12" -- "$exe" verify run1 --frames 12
expect 2 "--skip-frames-before 9 leaves none of the selected frames to check \(the last is at t = 0.789" -- "$exe" verify run1 --skip-frames-before 9
expect 2 "--frames 'x': 'x' is not a frame number" -- "$exe" verify run1 --frames x
# limits exceeded: exit 1, each named
expect 1 'exceeded: frame [0-9]+ \(t = [0-9.e-]+ s\): vertex [0-9]+ moves at' -- "$exe" verify run1 --max-speed-ratio 0.1
grep -q '"pass": false' run1/verify.json && ok || bad "verify.json lacks pass: false"
expect 1 'FAIL: limits' -- "$exe" verify run1 --max-depth 0 --frames 8
# bad input: exit 2 with the file named, never a crash
expect 2 "nothing: output directory does not exist" -- "$exe" verify nothing
expect 2 "'verify' needs an output directory" -- "$exe" verify
expect 2 "--max-depth expects a non-negative number, got 'deep'" -- "$exe" verify run1 --max-depth deep
expect 2 "unknown option '--max-dept' \(did you mean '--max-depth'\?\)" -- "$exe" verify run1 --max-dept 1
mkdir -p empty
expect 2 "empty/mesh.h5: file does not exist" -- "$exe" verify empty
cp -r run1 broken
echo "not HDF5" > broken/mesh.h5
expect 2 "broken/mesh.h5: not a readable HDF5 file" -- "$exe" verify broken
cp run1/mesh.h5 broken/mesh.h5
head -c 1000 run1/frames/000003.h5 > broken/frames/000003.h5
expect 2 "broken/frames/000003.h5: not a readable HDF5 file" -- "$exe" verify broken
rm -rf broken/frames/*
expect 2 "no frame files" -- "$exe" verify broken
# a frame of another run (different vertex count): its shape is named
"$exe" run "$data/scenes/pile.yaml" --output other --steps 2 --quiet > /dev/null 2>&1
cp other/frames/000000.h5 broken/frames/000000.h5
expect 2 "broken/frames/000000.h5: dataset 'velocities' should have 104 rows of 3" -- "$exe" verify broken

# 4,096 objects: mesh.h5's object table (one text attribute of /mesh, 227 KiB here) is
# past the 64 KiB HDF5 keeps in a header; the run failed to create it before
expect 0 'done: 1 steps' -- "$exe" run "$data/scenes/many_objects.yaml" --output many --quiet
expect 0 'verify many: 4096 objects' -- "$exe" verify many --frames last

# under MPI the ranks share the frames (rank 0 reports): the same lines and JSON as one
# process, every rank exits with rank 0's status
"$exe" verify run1 --json one.json > one.txt 2>&1
"$mpiexec" --oversubscribe -n 3 "$exe" verify run1 --json three.json > three.txt 2>&1
cmp -s one.json three.json && ok || bad "verify on 3 ranks: three.json differs from one process's one.json"
[ "$(grep -cE '^ +[0-9]+ +[0-9]+ ' three.txt)" = 11 ] && ok || bad "verify on 3 ranks: expected 11 frame lines"
diff <(grep -vE '^(summary|json):' one.txt) <(grep -vE '^(summary|json):' three.txt) > /dev/null && ok ||
  bad "verify on 3 ranks: the report differs from one process's"
grep -qE '^summary: 11 frame\(s\) checked in [0-9.e+-]+ s by 3 processes' three.txt && ok || bad "verify on 3 ranks: summary line"
# a frame that rank 1 of 3 reads is damaged: exit 2 naming it, one message, no hang
cp -r run1 broken3
head -c 1000 run1/frames/000001.h5 > broken3/frames/000001.h5
expect 2 "broken3/frames/000001.h5: not a readable HDF5 file" -- "$mpiexec" --oversubscribe -n 3 "$exe" verify broken3
[ "$("$mpiexec" --oversubscribe -n 3 "$exe" verify broken3 2>&1 | grep -c 'softcontact: error')" = 1 ] && ok ||
  bad "verify on 3 ranks with a damaged frame: expected one error message"
expect 0 'PASS' -- "$mpiexec" --oversubscribe -n 2 "$exe" verify run1 --frames last
expect 1 'FAIL' -- "$mpiexec" --oversubscribe -n 2 "$exe" verify run1 --max-speed-ratio 0.1
expect 2 "nothing: output directory does not exist" -- "$mpiexec" --oversubscribe -n 2 "$exe" verify nothing
expect 0 'verify \(every 5 steps' -- "$mpiexec" --oversubscribe -n 2 "$exe" run "$data/scenes/small.yaml" --output mpi2 --steps 20 --verify-every 5 --quiet

echo "cli.verify: $passes passed, $fails failed"
[ "$fails" = 0 ]
