// The collision module's parallel loops (src/collide/parallel.hpp) and LoopFailure
// (softcontact/loop_failure.hpp) when a body throws:
// the exception of the lowest index reaches the caller, on any thread count, instead of
// leaving the OpenMP region (std::terminate).
#include <gtest/gtest.h>

#include <omp.h>

#include <atomic>
#include <new>
#include <stdexcept>
#include <string>

#include "collide/parallel.hpp"

using namespace softcontact::collide;

namespace {

template <class Loop>
void expect_lowest_thrown(Loop loop, const char* name) {
  for (int threads : {1, 2, 3}) {
    omp_set_num_threads(threads);
    std::atomic<int> ran{0};
    std::string caught;
    try {
      loop(1000, [&](std::size_t i, int) {
        ++ran;
        if (i == 700 || i == 300 || i == 901) throw std::runtime_error("item " + std::to_string(i));
      });
    } catch (const std::runtime_error& e) {
      caught = e.what();
    }
    EXPECT_EQ(caught, "item 300") << name << ", " << threads << " threads";
    EXPECT_EQ(ran.load(), 1000) << name << ": every other item still ran";
    bool bad_alloc = false;
    try {
      loop(50, [](std::size_t i, int) {
        if (i == 17) throw std::bad_alloc();
      });
    } catch (const std::bad_alloc&) {
      bad_alloc = true;
    }
    EXPECT_TRUE(bad_alloc) << name << ", " << threads << " threads";
  }
  omp_set_num_threads(1);
}

}  // namespace

TEST(CollideParallel, ABodyThatThrowsReachesTheCallerWithTheLowestIndex) {
  expect_lowest_thrown([](std::size_t n, auto&& f) { parallel_for(n, f); }, "parallel_for");
  expect_lowest_thrown([](std::size_t n, auto&& f) { parallel_for_dynamic(n, f); }, "parallel_for_dynamic");
}

// The form of the loops outside src/collide (src/contact/coupled_closure.cpp): a try
// block around the body of a loop with reductions, LoopFailure::record in its handler.
// The sums keep every other item's part; the lowest index's exception is rethrown.
TEST(LoopFailure, ATryBlockInALoopWithReductionsRethrowsTheLowestIndex) {
  for (int threads : {1, 2, 3}) {
    omp_set_num_threads(threads);
    softcontact::LoopFailure failure;
    long long sum = 0;
#pragma omp parallel for schedule(dynamic, 1) reduction(+ : sum)
    for (std::ptrdiff_t i = 0; i < 200; ++i) {
      try {
        if (i % 50 == 49) throw std::runtime_error("item " + std::to_string(i));
        sum += i;
      } catch (...) {
        failure.record(static_cast<std::size_t>(i));
      }
    }
    std::string caught;
    try {
      failure.rethrow();
    } catch (const std::runtime_error& e) {
      caught = e.what();
    }
    EXPECT_EQ(caught, "item 49") << threads << " threads";
    EXPECT_EQ(sum, 199 * 200 / 2 - (49 + 99 + 149 + 199)) << threads << " threads";
  }
  omp_set_num_threads(1);
}
