#include "softcontact/memory.hpp"

#include <malloc.h>
#include <sys/resource.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <vector>

#include "softcontact/error.hpp"
#include "softcontact/mpi_util.hpp"

namespace softcontact {

namespace {

// The model (docs/reliability.md, "Memory"): a least-squares fit (relative errors) to
// the peak resident memory (VmHWM) of 'softcontact run' for 10 steps, frames every 5, of
// 12 runs: one corotational box or slab of 6 thousand to 1.3 million tets on a plate on 1
// rank, and two equal boxes on 1 and 2 ranks. Largest error 3.3 %.
constexpr double kFixedBytes = 43.1 * 1024 * 1024;  // MPI, PETSc, HDF5, the program
constexpr double kSceneBytesPerTet = 274;           // single-copy entries' meshes a rank made
constexpr double kObjectBytes = 1500;               // what every rank knows of each object (shape, placement, layout)
constexpr double kOwnedBytesPerTet = 120;           // state of the owned objects: forces,
constexpr double kOwnedBytesPerVertex = 1514;       // collision, contact, output

// A field "Name:   123 kB" of a /proc file (/proc/self/status, /proc/meminfo) [bytes];
// 0 when missing.
double proc_field(const char* file, const char* name) {
  std::ifstream in(file);
  std::string line;
  const std::string key = std::string(name) + ":";
  while (std::getline(in, line))
    if (line.rfind(key, 0) == 0) {
      std::istringstream s(line.substr(key.size()));
      double kb = 0;
      s >> kb;
      return kb * 1024;
    }
  return 0;
}
double status_field(const char* name) { return proc_field("/proc/self/status", name); }
double meminfo_field(const char* name) { return proc_field("/proc/meminfo", name); }

}  // namespace

MemoryEstimate estimate_memory(const Scene& scene, int nranks) {
  MemoryEstimate e;
  const std::int64_t n = std::max(nranks, 1);
  std::int64_t big_t = 0, big_v = 0;
  // Copies of multi-copy entries are held only where owned or ghosted (Scene::drop_meshes);
  // the mesh of a single-copy entry by the rank that made it, object k's by rank k % n
  // (docs/architecture.md, "Who reads which mesh file"), while the scene is read and the
  // World built, and then dropped likewise: the largest rank's share counts towards the
  // peak. (Files that several single-copy entries name are held by every rank; not
  // counted so.)
  std::vector<std::int64_t> made_t(static_cast<std::size_t>(n), 0);
  for (std::size_t k = 0; k < scene.objects.size(); ++k) {
    const ObjectShape& s = scene.shape(k);
    const auto t = static_cast<std::int64_t>(s.tets), v = static_cast<std::int64_t>(s.vertices);
    if (!scene.objects[k].placement.is_copy()) made_t[k % static_cast<std::size_t>(n)] += t;
    e.tets += t;
    e.vertices += v;
    big_t = std::max(big_t, t);
    big_v = std::max(big_v, v);
  }
  const std::int64_t everywhere_t = *std::max_element(made_t.begin(), made_t.end());
  e.rank_tets = std::max(big_t, (e.tets + n - 1) / n);
  e.rank_vertices = std::max(big_v, (e.vertices + n - 1) / n);
  e.fixed = kFixedBytes;
  e.per_rank = kFixedBytes + kSceneBytesPerTet * static_cast<double>(everywhere_t) +
               kObjectBytes * static_cast<double>(scene.objects.size()) +
               owned_state_bytes(static_cast<double>(e.rank_tets), static_cast<double>(e.rank_vertices));
  return e;
}

double owned_state_bytes(double tets, double vertices) {
  return kOwnedBytesPerTet * tets + kOwnedBytesPerVertex * vertices;
}

MemoryLimits memory_limits(MPI_Comm comm) {
  MemoryLimits m;
  rlimit r{};
  if (getrlimit(RLIMIT_AS, &r) == 0 && r.rlim_cur != RLIM_INFINITY) m.address_space = static_cast<double>(r.rlim_cur);
  MPI_Comm node;
  MPI_Comm_split_type(comm, MPI_COMM_TYPE_SHARED, 0, MPI_INFO_NULL, &node);
  m.ranks_on_node = comm_size(node);
  MPI_Comm_free(&node);
  m.node_available = meminfo_field("MemAvailable");
  if (m.node_available <= 0) m.node_available = meminfo_field("MemTotal");
  if (m.node_available > 0) m.node_share = m.node_available / m.ranks_on_node;
  return m;
}

double address_space_needed(const MemoryEstimate& e) {
  return e.per_rank + std::max(0.0, virtual_size_bytes() - status_field("VmRSS"));
}

void check_memory_fits(MPI_Comm comm, const MemoryEstimate& e, const std::string& where) {
  // SOFTCONTACT_MEMORY_CHECK=off: run anyway (to measure, or when the estimate is wrong
  // for a scene; the same on every rank, as the environment of one mpirun is).
  if (const char* off = std::getenv("SOFTCONTACT_MEMORY_CHECK"); off && std::string(off) == "off") return;
  const MemoryLimits lim = memory_limits(comm);
  // The address-space limit counts virtual memory: the libraries, MPI's shared segments
  // and thread stacks the process has mapped already come on top of the estimate.
  const double overhead = address_space_needed(e) - e.per_rank;
  std::string why;
  if (lim.address_space > 0 && e.per_rank + overhead > lim.address_space) {
    why = "the estimated peak of " + format_bytes(e.per_rank) + " per rank, plus the " + format_bytes(overhead) +
          " of address space this process has mapped already, exceeds the rank's address-space limit of " +
          format_bytes(lim.address_space) + " (ulimit -v, RLIMIT_AS)";
  } else if (lim.node_share > 0 && e.per_rank > lim.node_share) {
    why = "the estimated peak of " + format_bytes(e.per_rank) + " per rank exceeds this node's available memory, " +
          format_bytes(lim.node_available) + " shared by " + std::to_string(lim.ranks_on_node) + " rank(s): " +
          format_bytes(lim.node_share) + " each";
  }
  // Any rank that cannot fit refuses for all (the lowest such rank's reason).
  int bad = why.empty() ? 0 : 1;
  MPI_Allreduce(MPI_IN_PLACE, &bad, 1, MPI_INT, MPI_MAX, comm);
  if (!bad) return;
  const int rank = comm_rank(comm), size = comm_size(comm);
  int first = why.empty() ? size : rank;
  MPI_Allreduce(MPI_IN_PLACE, &first, 1, MPI_INT, MPI_MIN, comm);
  long long len = static_cast<long long>(why.size());
  MPI_Bcast(&len, 1, MPI_LONG_LONG, first, comm);
  why.resize(static_cast<std::size_t>(len));
  MPI_Bcast(why.data(), static_cast<int>(len), MPI_CHAR, first, comm);
  std::ostringstream m;
  m << "the run cannot fit in memory: " << why << " (" << e.tets << " tets, " << e.vertices
    << " vertices; the largest share of one rank " << e.rank_tets
    << " tets). Try more ranks on more nodes (objects are the unit of distribution), fewer ranks per node, a "
       "higher limit, or coarser meshes (docs/reliability.md, \"Memory\")";
  throw InputError(where, 0, m.str());
}

double peak_rss_bytes() {
  const double hwm = status_field("VmHWM");
  if (hwm > 0) return hwm;
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_maxrss) * 1024;  // Linux: KiB
}

double virtual_size_bytes() { return status_field("VmSize"); }

double heap_in_use_bytes() {
#if defined(__GLIBC__) && (__GLIBC__ > 2 || (__GLIBC__ == 2 && __GLIBC_MINOR__ >= 33))
  // An allocator that replaces glibc's (AddressSanitizer's, tcmalloc) leaves mallinfo2
  // all zeros: unknown then, never "nothing in use".
  const struct mallinfo2 m = mallinfo2();
  const double bytes = static_cast<double>(m.uordblks + m.hblkhd);
  return bytes > 0 ? bytes : -1;
#else
  return -1;
#endif
}

std::string format_bytes(double bytes) {
  char buf[64];
  const double mib = bytes / (1024.0 * 1024.0);
  if (mib >= 1024) std::snprintf(buf, sizeof buf, "%.2f GiB", mib / 1024);
  else std::snprintf(buf, sizeof buf, "%.0f MiB", mib);
  return buf;
}

}  // namespace softcontact
