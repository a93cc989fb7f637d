#!/usr/bin/env bash
# The test suite under AddressSanitizer and UndefinedBehaviorSanitizer: builds the unit
# and MPI test executables and the command-line program with g++ -O1 -g
# -fsanitize=address,undefined -fno-sanitize-recover=undefined into build-asan, then runs
# ctest on them (labels unit, mpi, cli by default, without cli.reliability, whose kills
# and signals test the process, not memory, cli.memory, whose address-space limits
# ASan's shadow memory cannot run under, and cli.weak_memory, whose peaks under ASan
# measure its shadow memory and quarantine, not ours; and without six long physics runs
# of the unit tests, named below with the reason). Any sanitizer report fails its test.
#
# Usage: bash tools/sanitize.sh [ctest arguments]
#   (default: the unit tests as GoogleTest shards, then ctest -L 'mpi|cli'
#   -E '^(mpi[.]np[24]|cli[.](reliability|memory|weak_memory|edge_contact[.].*|self_contact[.].*))$')
# cli.edge_contact.* and cli.self_contact.* are whole runs with the check of softcontact
# verify after every step, bounds on physics; their kernels (edge contacts, self-contact,
# verify) run under the sanitizers in the unit tests (EdgeContacts.*, Verify.*,
# CollisionDetector.Self*) and the run loop in cli.commands, so they are left out here
# (200 of the 1,250 test-seconds under ASan). The MPI tests run on 1 and 3 ranks here (one
# rank, and an uneven split with a rank between two others); on 2 and 4 ranks they run
# without the sanitizers in the default suite. Under ASan the four took 197 s of wall
# time and 571 core-seconds in CI, np2 and np4 106 s and 357 of them.
# Environment: ASAN_BUILD_DIR (default build-asan), JOBS.
#
# Leaks: Open MPI (and the PMIx/hwloc/libevent libraries under it) keeps allocations it
# never frees, by design, until the process exits; every test executable here starts MPI
# (tests/test_main.cpp), so LeakSanitizer would fail each of them on memory we cannot
# free. tools/lsan.supp suppresses leaks whose allocation stack goes through those
# libraries only; leak checking stays on for our own code, in every test.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build=${ASAN_BUILD_DIR:-$root/build-asan}
jobs=${JOBS:-$(OMP_NUM_THREADS= nproc)}
defaults=0
if [ $# -eq 0 ]; then
  defaults=1
  set -- -L 'mpi|cli' -E '^(mpi[.]np[24]|cli[.](reliability|memory|weak_memory|edge_contact[.].*|self_contact[.].*))$'
fi

# The same Debian packages as tools/setup.sh (g++ brings the sanitizer runtimes), which
# installs them: a test installs nothing.
packages=(g++ make cmake pkg-config libopenmpi-dev openmpi-bin petsc-dev libmetis-dev libhdf5-openmpi-dev
          libeigen3-dev libyaml-cpp-dev libgtest-dev)
source "$root/tools/packages.sh"
require_installed "sanitize.sh" "bash tools/setup.sh --sanitizers" "${packages[@]}"

# The sanitizer options hold while the build runs too: gtest_discover_tests runs the
# test executables to list their tests.
# fast_unwind_on_malloc=0: Open MPI's libraries have no frame pointers, and the fast
# unwinder then stops inside them, leaving "<unknown module>" stacks that no suppression
# can match. Components stay loaded (no dlclose) so that their frames keep their names.
export ASAN_OPTIONS=${ASAN_OPTIONS:-abort_on_error=1:detect_leaks=1:strict_init_order=1:fast_unwind_on_malloc=0}
export OMPI_MCA_mca_base_component_disable_dlclose=1 PMIX_MCA_mca_base_component_disable_dlclose=1
export LSAN_OPTIONS=${LSAN_OPTIONS:-suppressions=$root/tools/lsan.supp:print_suppressions=0}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
# Open MPI's shared-memory transport maps segments that ASan's allocator does not know;
# single-copy (CMA) transfers between ranks read memory outside our process, which ASan
# cannot track either. Use the plain copy-in/copy-out path.
export OMPI_MCA_btl_vader_single_copy_mechanism=none
source "$root/tools/env.sh"

flags="-fsanitize=address,undefined -fno-sanitize-recover=undefined -fno-omit-frame-pointer"
# -g1: line tables and function names only, which is what a sanitizer report prints
# (file:line of every frame, inlined ones included); no local variables. The build takes
# about a third less time than with -g (test_verify.cpp 13.1 -> 8.1 s, coupled_closure.cpp
# 24.6 -> 17.0 s). For a debugger session on a report, rebuild with -g.
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_C_COMPILER=gcc -DCMAKE_CXX_COMPILER=g++ \
      -DCMAKE_C_FLAGS="$flags" -DCMAKE_CXX_FLAGS="$flags" -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1 -DNDEBUG" \
      -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=address,undefined" -DSOFTCONTACT_WITH_TESTS=ON >/dev/null
start=$(date +%s)
cmake --build "$build" -j "$jobs" --target softcontact_tests softcontact_mpi_tests softcontact_exe
echo "sanitize.sh: build took $(( $(date +%s) - start )) s"

cores=$(OMP_NUM_THREADS= nproc)
cd "$build"
rc=0
if [ $defaults -eq 1 ]; then
  # The unit tests (label 'unit': the softcontact_tests executable) run as GoogleTest
  # shards, not one process per test as ctest runs them: under the sanitizers each start
  # (MPI_Init, ASan's shadow memory) costs about 2.5 s, which was 250 starts and about 5 of
  # the 15 minutes of this script. Three shards per core, `cores` of them at a time: with
  # one shard per core the two took 2.7 and 5.2 min (GoogleTest deals tests round-robin,
  # and the costly ones fell unevenly). LeakSanitizer checks each shard at its exit, over
  # all of its tests. Each shard leaves its exit status in unit_shard_K.rc.
  #
  # Six long physics runs are left out here (they run without the sanitizers in the
  # default suite): under ASan they were 324 of the unit tests' 835 test-seconds
  # (2026-12-02), and every kernel they run, runs here in shorter tests: friction
  # sticking and sliding (ContactPhysics.SlidingBoxStopsAfterCoulombDistance,
  # BoxDroppedOnFloorRestsWithContactForceEqualToWeight, the archway's short runs),
  # bodies stacked and deformable bodies meeting (Inputs/ShippedScene.* default,
  # chess500, torus_drop), every model and integrator (ContactPhysics.EveryModelAndIntegrator*,
  # ImplicitEuler.StableAtTwentyTimesTheExplicitLimit, Determinism.*). What they add is
  # length: thousands of steps, which finds drift, not memory errors.
  long_physics=ContactPhysics.BoxOnInclineSticksOrSlidesByCoulomb:ContactPhysics.BoxOnInclineSticksWithoutDamping
  long_physics+=:ContactPhysics.ElasticBarsExchangeVelocitiesWithoutGainingEnergy
  long_physics+=:ContactPhysics.StackOfThreeBoxesCarriesTheWeightAbove
  long_physics+=:VerletEnergy.BoundedWithoutDriftAndQuadraticInDt:ImplicitEuler.MatchesVerletAtSmallSteps
  start=$(date +%s)
  shards=$((3 * cores))
  run_shard() {
    local status=0
    (cd tests && OMP_NUM_THREADS=1 GTEST_TOTAL_SHARDS=$shards GTEST_SHARD_INDEX=$1 \
       ./softcontact_tests --gtest_brief=1 --gtest_filter="-$long_physics" >"unit_shard_$1.log" 2>&1) || status=$?
    echo "$status" >"tests/unit_shard_$1.rc"
  }
  rm -f tests/unit_shard_*.rc
  for ((shard = 0; shard < shards; ++shard)); do
    while [ "$(jobs -rp | wc -l)" -ge "$cores" ]; do wait -n || true; done
    run_shard "$shard" &
  done
  wait
  for ((shard = 0; shard < shards; ++shard)); do
    if [ "$(cat "tests/unit_shard_$shard.rc" 2>/dev/null)" != 0 ]; then
      rc=1
      echo "sanitize.sh: unit tests, shard $((shard + 1)) of $shards failed ($build/tests/unit_shard_$shard.log):"
      tail -n 60 "tests/unit_shard_$shard.log"
    fi
  done
  echo "sanitize.sh: unit tests took $(( $(date +%s) - start )) s"
fi
start=$(date +%s)
# The 'sanitize' tests would run this script again: never inside it.
ctest --output-on-failure -j "$cores" -LE 'sanitize|long|render|validation|scenes|extended' "$@" || rc=$?
echo "sanitize.sh: ctest took $(( $(date +%s) - start )) s"
exit "$rc"
