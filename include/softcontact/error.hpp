#pragma once
// Two tiers of errors (style.md, after MFEM_VERIFY/MFEM_ASSERT and LAMMPS error->all):
//  - InputError: always-on checks of what a user gave us (scene, mesh, command line).
//    It names the file, the line or element, and what was expected. The application
//    turns it into one message and exit status 2, never a stack trace.
//  - SC_ASSERT: internal invariants, compiled in debug builds only.
#include <cassert>
#include <cstdint>
#include <stdexcept>
#include <string>

namespace softcontact {

/// Exit status for bad input (scene, mesh, command line, existing output directory).
inline constexpr int kExitInputError = 2;

/// A problem with user input. `where()` is "file:line" (or "file" when no line applies);
/// `what()` is the full message, "file:line: detail".
class InputError : public std::runtime_error {
public:
  InputError(const std::string& file, std::int64_t line, const std::string& detail);
  explicit InputError(const std::string& detail);

  const std::string& file() const noexcept { return file_; }
  std::int64_t line() const noexcept { return line_; }
  const std::string& detail() const noexcept { return detail_; }

private:
  std::string file_;
  std::int64_t line_ = 0;  // 1-based; 0 when the error has no line
  std::string detail_;
};

/// A failure of the run itself (I/O, numerical), not of its input. Exit status 1.
class RuntimeFailure : public std::runtime_error {
public:
  using std::runtime_error::runtime_error;
};

/// A failure of the run that every rank detects together, thrown on every rank with the
/// same message (the output directory or a file cannot be created, a rename failed):
/// rank 0 prints it once and every rank ends with exit status 1, without MPI_Abort.
/// A RuntimeFailure that is not collective is one rank's alone: that rank prints it and
/// ends the job with MPI_Abort, since the others may be waiting in a collective call.
class CollectiveFailure : public RuntimeFailure {
public:
  using RuntimeFailure::RuntimeFailure;
};

/// Exit status when the numerical-failure guard stops a run (docs/reliability.md).
inline constexpr int kExitNumericalFailure = 3;

/// The simulation became unphysical (non-finite positions, runaway speed or energy,
/// inverted elements). Thrown on every rank together, with the same message: where
/// (step, object, element) and what to try.
class NumericalFailure : public RuntimeFailure {
public:
  using RuntimeFailure::RuntimeFailure;
};

}  // namespace softcontact

#ifndef NDEBUG
#define SC_ASSERT(cond) assert(cond)
#else
#define SC_ASSERT(cond) ((void)0)
#endif
