#pragma once
// The command line: softcontact {run,check,bench,info} ... Returns the process exit status:
// 0 success, 1 failure of the run itself, 2 bad input (scene, mesh, command line).
#include <mpi.h>

#include <iosfwd>

namespace softcontact {

int run_cli(int argc, const char* const* argv, MPI_Comm comm, std::ostream& out, std::ostream& err);

}  // namespace softcontact
