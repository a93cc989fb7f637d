#pragma once
// Exceptions out of OpenMP loops (docs/reliability.md, "Memory").
//
// An exception may not leave an OpenMP region (the runtime calls std::terminate: an abort
// with a stack trace), yet loop bodies allocate, and an exhausted memory must reach the
// caller as a std::bad_alloc to be reported as one. A loop keeps one LoopFailure; each
// body runs through run() (or in a try block whose handler calls record()); after the
// loop rethrow() throws the exception of the lowest index that threw, the same on any
// thread count. The other iterations still run.
#include <cstddef>
#include <exception>
#include <utility>

namespace softcontact {

class LoopFailure {
public:
  /// Keeps the exception being handled when it comes from a lower index than the one kept.
  void record(std::size_t i) noexcept {
#pragma omp critical(softcontact_loop_failure)
    if (!error_ || i < index_) {
      error_ = std::current_exception();
      index_ = i;
    }
  }
  /// f(args...) for iteration i; what it throws is recorded, not propagated.
  template <class F, class... A>
  void run(std::size_t i, F& f, A&&... args) noexcept {
    try {
      f(std::forward<A>(args)...);
    } catch (...) {
      record(i);
    }
  }
  void rethrow() const {
    if (error_) std::rethrow_exception(error_);
  }

private:
  std::exception_ptr error_;
  std::size_t index_ = 0;
};

}  // namespace softcontact
