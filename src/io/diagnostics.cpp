#include "softcontact/diagnostics.hpp"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>

#include "h5_util.hpp"
#include "softcontact/error.hpp"
#include "softcontact/mpi_util.hpp"

namespace softcontact {

void reduce_mechanics(MPI_Comm comm, const Scene& scene, const World& w, StepDiagnostics& d,
                      const ElasticMeasures* elastic, const double* contact_force) {
  // kinetic, potential, px, py, pz, elastic energy, inverted tets (a count, exact as a
  // double far beyond any mesh size), contact force x, y, z and its norms' sum
  constexpr int K = 11;
  const Vec3& g = scene.sim.gravity;
  std::vector<double> mine(K * w.owned_objects.size(), 0.0);
  // Owned vertices are stored object by object in owned_objects order.
  std::size_t o = 0;
  for (std::size_t i = 0; i < w.n_owned; ++i) {
    while (w.owned_objects[o] != w.vertex_object[i]) ++o;
    if (contact_force) {
      const double* f = &contact_force[3 * i];
      double* s = &mine[K * o];
      for (int c = 0; c < 3; ++c) s[7 + c] += f[c];
      s[10] += std::sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
    }
    if (w.inv_mass[i] == 0) continue;
    const double m = w.mass[i];
    const double* v = &w.v[3 * i];
    const double* x = &w.x[3 * i];
    double* s = &mine[K * o];
    s[0] += 0.5 * m * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    s[1] -= m * (g[0] * x[0] + g[1] * x[1] + g[2] * x[2]);
    for (int c = 0; c < 3; ++c) s[2 + c] += m * v[c];
  }
  if (elastic)
    for (std::size_t k = 0; k < w.owned_objects.size(); ++k) {
      mine[K * k + 5] = elastic->energy[k];
      mine[K * k + 6] = static_cast<double>(elastic->inverted[k]);
    }
  const int rank = comm_rank(comm), size = comm_size(comm);
  const int count = static_cast<int>(mine.size());
  std::vector<int> counts(size), displs(size);
  MPI_Gather(&count, 1, MPI_INT, counts.data(), 1, MPI_INT, 0, comm);
  std::vector<double> all;
  std::vector<int> order;  // object index of each gathered block
  if (rank == 0) {
    int off = 0;
    for (int r = 0; r < size; ++r) {
      displs[r] = off;
      off += counts[r];
    }
    all.resize(static_cast<std::size_t>(off));
  }
  MPI_Gatherv(mine.data(), count, MPI_DOUBLE, all.data(), counts.data(), displs.data(), MPI_DOUBLE, 0, comm);
  double totals[K] = {0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0};
  if (rank == 0) {
    // Blocks arrive grouped by rank; re-sort them into object order before summing.
    std::vector<const double*> by_object(w.layout.size(), nullptr);
    std::vector<std::size_t> next(size, 0);
    for (std::size_t k = 0; k < w.layout.size(); ++k) {
      const int r = w.layout[k].rank;
      by_object[k] = all.data() + displs[r] + K * next[r]++;
    }
    for (std::size_t k = 0; k < w.layout.size(); ++k)
      for (int c = 0; c < K; ++c) totals[c] += by_object[k][c];
  }
  MPI_Bcast(totals, K, MPI_DOUBLE, 0, comm);
  d.kinetic_energy = totals[0];
  d.potential_energy = totals[1];
  d.momentum = {totals[2], totals[3], totals[4]};
  d.elastic_energy = totals[5];
  d.inverted_elements = static_cast<std::int64_t>(totals[6]);
  if (contact_force)
    d.contact_force_balance = totals[10] > 0 ? std::hypot(totals[7], totals[8], totals[9]) / totals[10] : 0;
}

const char* DiagnosticsCsv::header() {
  return "step,time,kinetic_energy,elastic_energy,potential_energy,momentum_x,momentum_y,momentum_z,"
         "contacts,residual_penetration,contact_force_balance,inverted_elements,edge_contacts,"
         "t_forces,t_integrate,t_detect,t_depth,t_contact,t_comm,t_output,t_total";
}

void DiagnosticsCsv::open(const std::string& path) {
  out_.open(path, std::ios::trunc);
  if (!out_) throw RuntimeFailure("cannot create '" + path + "'");
  out_ << header() << '\n';
  out_.flush();
}

void DiagnosticsCsv::resume(const std::string& path, std::int64_t last_step) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    open(path);
    return;
  }
  std::stringstream all;
  all << in.rdbuf();
  in.close();
  const std::string text = all.str();
  std::string kept = std::string(header()) + '\n';
  std::size_t at = text.find('\n');  // after the header
  while (at != std::string::npos && at + 1 < text.size()) {
    const std::size_t end = text.find('\n', at + 1);
    if (end == std::string::npos) break;  // a torn last row
    const std::string row = text.substr(at + 1, end - at);
    char* stop = nullptr;
    const long long step = std::strtoll(row.c_str(), &stop, 10);
    if (stop == row.c_str() || *stop != ',' || step > last_step) break;
    kept += row;
    at = end;
  }
  h5::write_text_atomically(path, kept);
  out_.open(path, std::ios::app);
  if (!out_) throw RuntimeFailure("cannot append to '" + path + "'");
}

void DiagnosticsCsv::write(const StepDiagnostics& d) {
  if (!out_.is_open()) return;
  char buf[1024];
  const PhaseTimes& t = d.seconds;
  std::snprintf(buf, sizeof buf,
                "%lld,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%lld,%.17g,%.17g,%lld,%lld,%.6e,%.6e,%.6e,%.6e,%.6e,%.6e,%.6e,%.6e\n",
                static_cast<long long>(d.step), d.time, d.kinetic_energy, d.elastic_energy, d.potential_energy,
                d.momentum[0], d.momentum[1], d.momentum[2], static_cast<long long>(d.contacts),
                d.residual_penetration, d.contact_force_balance, static_cast<long long>(d.inverted_elements), static_cast<long long>(d.edge_contacts),
                t.forces, t.integrate, t.detect, t.depth, t.contact, t.comm, t.output, t.total());
  out_ << buf;
  out_.flush();  // a killed batch job keeps every row written so far
}

}  // namespace softcontact
