// softcontact: the executable. MPI (threads funnelled through the master thread, which
// is what OpenMP inside each rank needs) and PETSc are started here and nowhere else.
#include <mpi.h>
#include <petscsys.h>

#include <iostream>

#include "softcontact/cli.hpp"

int main(int argc, char** argv) {
  int provided = 0;
  MPI_Init_thread(&argc, &argv, MPI_THREAD_FUNNELED, &provided);
  // PETSc takes its options from PETSC_OPTIONS, so our command line stays our own.
  if (PetscInitializeNoArguments() != 0) {
    std::cerr << "softcontact: error: PETSc failed to initialise\n";
    MPI_Finalize();
    return 1;
  }
  const int code = softcontact::run_cli(argc, argv, MPI_COMM_WORLD, std::cout, std::cerr);
  PetscFinalize();
  MPI_Finalize();
  return code;
}
