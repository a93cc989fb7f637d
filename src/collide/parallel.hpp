#pragma once
// The OpenMP of src/collide, in one place (style.md: pragmas in one or two helpers).
//
// Determinism: every loop body writes only its own outputs (slot i, or the buffer of
// its thread). With the static schedule thread t runs one contiguous, ascending block of
// indices, so per-thread buffers concatenated in thread order list their items in index
// order whatever the thread count; callers sort such lists anyway where order matters.
// No atomics on shared arrays anywhere. What a body throws is rethrown after the loop
// (softcontact/loop_failure.hpp).
#include <omp.h>

#include <cstddef>
#include <vector>

#include "softcontact/loop_failure.hpp"

namespace softcontact::collide {

inline int max_threads() { return omp_get_max_threads(); }

/// f(i, thread) for i in [0, n), static schedule.
template <class F>
void parallel_for(std::size_t n, F&& f) {
  const auto count = static_cast<std::ptrdiff_t>(n);
  LoopFailure failure;
#pragma omp parallel for schedule(static)
  for (std::ptrdiff_t i = 0; i < count; ++i)
    failure.run(static_cast<std::size_t>(i), f, static_cast<std::size_t>(i), omp_get_thread_num());
  failure.rethrow();
}

/// f(i, thread) for i in [0, n), dynamic schedule: for items of very uneven cost whose
/// results go to slots fixed in advance (so the schedule cannot change them).
template <class F>
void parallel_for_dynamic(std::size_t n, F&& f) {
  const auto count = static_cast<std::ptrdiff_t>(n);
  LoopFailure failure;
#pragma omp parallel for schedule(dynamic, 1)
  for (std::ptrdiff_t i = 0; i < count; ++i)
    failure.run(static_cast<std::size_t>(i), f, static_cast<std::size_t>(i), omp_get_thread_num());
  failure.rethrow();
}

/// Per-thread buffers, reused between calls: one per possible thread, each cleared.
template <class T>
void reset_buffers(std::vector<std::vector<T>>& buffers) {
  buffers.resize(static_cast<std::size_t>(max_threads()));
  for (auto& b : buffers) b.clear();
}

/// Appends the buffers to `out` in thread order.
template <class T>
void concatenate(const std::vector<std::vector<T>>& buffers, std::vector<T>& out) {
  std::size_t n = out.size();
  for (const auto& b : buffers) n += b.size();
  out.reserve(n);
  for (const auto& b : buffers) out.insert(out.end(), b.begin(), b.end());
}

}  // namespace softcontact::collide
