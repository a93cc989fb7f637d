# Sourced by the tools: lets Open MPI run as root (containers, CI) and oversubscribe
# cores, without touching the user's shell. One OpenMP thread per rank unless asked.
export OMPI_ALLOW_RUN_AS_ROOT=1
export OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
export OMPI_MCA_rmaps_base_oversubscribe=1
export OMP_NUM_THREADS=${OMP_NUM_THREADS:-1}
# Idle OpenMP threads sleep instead of spinning: on a shared machine a spinning team
# waiting for a descheduled thread made 2-thread steps 15 times slower (docs/benchmarks.md).
# On a dedicated node, OMP_WAIT_POLICY=active may be a little faster.
export OMP_WAIT_POLICY=${OMP_WAIT_POLICY:-passive}
