#pragma once
// The command line: softcontact {run,check,bench,verify,info} ... Returns the process exit status:
// 0 success, 1 failure of the run itself (verify: a limit exceeded), 2 bad input (scene,
// mesh, command line, output directory).
#include <mpi.h>

#include <iosfwd>

namespace softcontact {

int run_cli(int argc, const char* const* argv, MPI_Comm comm, std::ostream& out, std::ostream& err);

}  // namespace softcontact
