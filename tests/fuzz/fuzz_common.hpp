#pragma once
// What every harness checks: an input is accepted, or rejected with softcontact::InputError
// carrying a message. Anything else thrown is a finding: it is printed and the process
// aborts, so that libFuzzer saves the input as a crash reproducer. Crashes, sanitizer
// reports, timeouts and allocations over -malloc_limit_mb are findings by themselves.
#include <cstdio>
#include <cstdlib>
#include <exception>

#include "softcontact/error.hpp"

namespace softcontact::fuzz {

/// With SOFTCONTACT_FUZZ_VERBOSE set, each input's outcome is printed ("accepted" or the
/// InputError's message): to see what a corpus file exercises.
inline bool verbose() {
  static const bool on = std::getenv("SOFTCONTACT_FUZZ_VERBOSE") != nullptr;
  return on;
}

template <class F>
void expect_accept_or_input_error(F&& f) {
  try {
    f();
    if (verbose()) std::fprintf(stderr, "fuzz: accepted\n");
  } catch (const InputError& e) {
    if (verbose()) std::fprintf(stderr, "fuzz: InputError: %s\n", e.what());
    if (e.detail().empty()) {
      std::fprintf(stderr, "fuzz: InputError without a message: '%s'\n", e.what());
      std::abort();
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fuzz: an exception other than InputError escaped: %s\n", e.what());
    std::abort();
  } catch (...) {
    std::fprintf(stderr, "fuzz: a non-std exception escaped\n");
    std::abort();
  }
}

/// Aborts with `what` when an accepted result breaks an invariant the readers promise.
inline void require(bool ok, const char* what) {
  if (!ok) {
    std::fprintf(stderr, "fuzz: accepted input breaks an invariant: %s\n", what);
    std::abort();
  }
}

}  // namespace softcontact::fuzz
