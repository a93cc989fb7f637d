// Deterministic fault injection (include/softcontact/fault.hpp, docs/reliability.md).
#include "softcontact/fault.hpp"

#include <signal.h>

#include <cstdlib>
#include <iostream>
#include <sstream>
#include <vector>

#include "softcontact/error.hpp"

namespace softcontact::fault {

namespace detail {
bool armed = false;
}

namespace {

enum class Action { kill, sigterm, sigint, ioerror, nan };

struct Fault {
  Action action = Action::kill;
  Point point = Point::step;
  std::int64_t step = 0;
  int rank = -1;  // -1: every rank
};

Fault g_fault;
int g_rank = 0;

constexpr const char* kVariable = "SOFTCONTACT_FAULT";
constexpr const char* kActions[] = {"kill", "sigterm", "sigint", "ioerror", "nan"};
constexpr const char* kPoints[] = {"step", "frame_write", "frame_rename", "frame_renamed",
                                   "checkpoint_write", "checkpoint_rename", "checkpoint_renamed"};

template <std::size_t N>
std::string list(const char* const (&words)[N]) {
  std::string s;
  for (std::size_t i = 0; i < N; ++i) s += (i ? ", " : "") + std::string(words[i]);
  return s;
}

template <std::size_t N>
int find(const char* const (&words)[N], const std::string& w) {
  for (std::size_t i = 0; i < N; ++i)
    if (w == words[i]) return static_cast<int>(i);
  return -1;
}

bool parse_integer(const std::string& s, long long& n) {
  if (s.empty() || s.find_first_not_of("0123456789") != std::string::npos || s.size() > 18) return false;
  n = std::stoll(s);
  return true;
}

}  // namespace

const char* name(Point p) { return kPoints[static_cast<int>(p)]; }

std::string io_error(Point p, const std::string& file) {
  return "cannot write '" + file + "': Input/output error (injected by " + kVariable + " at " + name(p) + ")";
}

void configure(int rank, int size) { configure(std::getenv(kVariable), rank, size); }

void configure(const char* value, int rank, int size) {
  detail::armed = false;
  if (value == nullptr || *value == '\0') return;
  const std::string text = value;
  auto bad = [&](const std::string& why) {
    throw InputError(std::string("environment variable ") + kVariable + "='" + text + "': " + why +
                     " (expected ACTION:POINT:STEP[:RANK], e.g. kill:frame_write:100:1; docs/reliability.md)");
  };
  std::vector<std::string> f;
  std::istringstream in(text);
  for (std::string part; std::getline(in, part, ':');) f.push_back(part);
  if (f.size() < 3 || f.size() > 4 || text.back() == ':') bad("expected 3 or 4 fields separated by ':'");
  const int a = find(kActions, f[0]);
  if (a < 0) bad("unknown action '" + f[0] + "' (one of " + list(kActions) + ")");
  const int p = find(kPoints, f[1]);
  if (p < 0) bad("unknown point '" + f[1] + "' (one of " + list(kPoints) + ")");
  Fault fault;
  fault.action = static_cast<Action>(a);
  fault.point = static_cast<Point>(p);
  if (fault.action == Action::nan && fault.point != Point::step) bad("'nan' applies at the point 'step' only");
  if (fault.action == Action::ioerror && fault.point == Point::step)
    bad("'ioerror' applies at a write or rename point, not at 'step'");
  long long n = 0;
  if (!parse_integer(f[2], n)) bad("the step '" + f[2] + "' is not a non-negative integer");
  fault.step = n;
  if (f.size() == 4 && f[3] != "all") {
    if (!parse_integer(f[3], n)) bad("the rank '" + f[3] + "' is not a non-negative integer or 'all'");
    if (n >= size) bad("rank " + f[3] + ", but the job has " + std::to_string(size) + " rank(s)");
    fault.rank = static_cast<int>(n);
  }
  if (fault.rank >= 0 && fault.rank != rank) return;  // another rank's fault
  g_fault = fault;
  g_rank = rank;
  detail::armed = true;
}

bool detail::hit(Point p, std::int64_t step) {
  if (p != g_fault.point || step < g_fault.step) return false;
  armed = false;  // once
  std::cerr << "softcontact: " << kVariable << ": injecting " << kActions[static_cast<int>(g_fault.action)] << " at "
            << name(p) << ", step " << step << ", rank " << g_rank << std::endl;
  switch (g_fault.action) {
    case Action::kill: ::raise(SIGKILL); break;
    case Action::sigterm: ::raise(SIGTERM); break;
    case Action::sigint: ::raise(SIGINT); break;
    case Action::ioerror:
    case Action::nan: return true;
  }
  return false;
}

}  // namespace softcontact::fault
