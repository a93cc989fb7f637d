// GoogleTest main for tests that use MPI (HDF5 output, diagnostics) and PETSc (implicit
// Euler): both are started around the tests, except when ctest only lists them.
#include <gtest/gtest.h>
#include <mpi.h>
#include <petscsys.h>

#include <cstdlib>
#include <cstring>

int main(int argc, char** argv) {
  bool listing = false;
  for (int i = 1; i < argc; ++i) listing = listing || std::strncmp(argv[i], "--gtest_list_tests", 18) == 0;
  ::testing::InitGoogleTest(&argc, argv);
  if (listing) return RUN_ALL_TESTS();
  // The tests run on one node: Open MPI's point-to-point over shared memory (ob1 with the
  // self and vader transports) rather than its default UCX, whose probing of the node's
  // transports made every MPI_Init 0.2 s longer (0.32 against 0.11 s, about a minute of
  // the default suite's 307 test processes on 2 cores). A value already set wins. Not for
  // the users' runs (tools/run.sh): a cluster's fabric needs UCX.
  setenv("OMPI_MCA_pml", "ob1", 0);
  setenv("OMPI_MCA_btl", "self,vader", 0);
  int provided = 0;
  MPI_Init_thread(&argc, &argv, MPI_THREAD_FUNNELED, &provided);
  // PETSc after MPI, so that it leaves MPI to us; its options come from PETSC_OPTIONS.
  if (PetscInitializeNoArguments() != 0) {
    MPI_Finalize();
    return 1;
  }
  int rank = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  if (rank != 0) {
    // Only rank 0 prints results; every rank runs every test (they are collective).
    auto& listeners = ::testing::UnitTest::GetInstance()->listeners();
    delete listeners.Release(listeners.default_result_printer());
  }
  const int failed = RUN_ALL_TESTS();
  int any = 0;
  MPI_Allreduce(&failed, &any, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
  PetscFinalize();
  MPI_Finalize();
  return any;
}
