# Sourced by the tools: lets Open MPI run as root (containers, CI) and oversubscribe
# cores, without touching the user's shell. One OpenMP thread per rank unless asked.
export OMPI_ALLOW_RUN_AS_ROOT=1
export OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
export OMPI_MCA_rmaps_base_oversubscribe=1
export OMP_NUM_THREADS=${OMP_NUM_THREADS:-1}
