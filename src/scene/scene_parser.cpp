// YAML scene -> validated Scene. Every user mistake becomes an InputError that names the
// file and line (yaml-cpp marks are 0-based; we report 1-based) and says what was
// expected; unknown keys get the nearest valid key suggested.
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <exception>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <set>
#include <sstream>
#include <system_error>

#include "softcontact/error.hpp"
#include "softcontact/forces.hpp"
#include "softcontact/mesh_io.hpp"
#include "softcontact/primitives.hpp"
#include "softcontact/scene.hpp"
#include "scene_internal.hpp"
#include "../model/material_registry.hpp"

namespace softcontact {

namespace {

/// The material laws' names in scene files, in ModelKind order (material_laws.hpp).
#define SOFTCONTACT_LAW_NAME(name) #name,
constexpr const char* kModelNames[] = {SOFTCONTACT_MATERIAL_LAWS(SOFTCONTACT_LAW_NAME)};
#undef SOFTCONTACT_LAW_NAME

}  // namespace

const char* to_string(ModelKind m) {
  const int k = static_cast<int>(m);
  return k >= 0 && k < kModelKinds ? kModelNames[k] : "?";
}

const char* to_string(DtBound b) { return b == DtBound::mesh ? "mesh" : "element"; }

const char* to_string(IntegratorKind i) {
  switch (i) {
    case IntegratorKind::verlet: return "verlet";
    case IntegratorKind::symplectic_euler: return "symplectic_euler";
    case IntegratorKind::implicit_euler: return "implicit_euler";
  }
  return "?";
}

double Material::wave_speed() const { return std::sqrt((lame_lambda() + 2 * lame_mu()) / density); }

double Motion::active_time(double t0, double t1) const {
  const double a = std::max(t0, start), b = std::min(t1, stop);
  return b > a ? b - a : 0.0;
}

namespace detail {

std::size_t edit_distance(const std::string& a, const std::string& b) {
  std::vector<std::size_t> prev(b.size() + 1), cur(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) prev[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    cur[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j)
      cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1)});
    std::swap(prev, cur);
  }
  return prev[b.size()];
}

std::string nearest(const std::string& word, const std::vector<std::string>& candidates) {
  std::string best;
  std::size_t best_d = std::numeric_limits<std::size_t>::max();
  for (const auto& c : candidates) {
    const std::size_t d = edit_distance(word, c);
    if (d < best_d) {
      best_d = d;
      best = c;
    }
  }
  // Only suggest something plausibly meant: at most a third of the letters changed.
  if (best_d <= std::max<std::size_t>(2, word.size() / 3)) return best;
  return {};
}

}  // namespace detail

namespace {

using detail::nearest;

/// Reads typed values from YAML nodes and turns every mistake into an InputError at the
/// node's line.
class Reader {
public:
  explicit Reader(std::string file) : file_(std::move(file)) {}

  const std::string& file() const { return file_; }

  [[noreturn]] void fail(const YAML::Node& at, const std::string& what) const {
    const auto mark = at.Mark();
    throw InputError(file_, mark.is_null() ? 0 : mark.line + 1, what);
  }

  void expect_map(const YAML::Node& n, const std::string& what) const {
    if (!n.IsMap()) fail(n, what + " must be a mapping of 'key: value' entries");
  }

  /// Rejects keys outside `allowed`, suggesting the nearest one.
  void check_keys(const YAML::Node& map, const std::vector<std::string>& allowed, const std::string& where) const {
    expect_map(map, where);
    for (auto it = map.begin(); it != map.end(); ++it) {
      if (!it->first.IsScalar()) fail(it->first, "expected a plain key (a name) in " + where + ", got a list or mapping as key");
      const std::string key = it->first.Scalar();
      if (std::find(allowed.begin(), allowed.end(), key) != allowed.end()) continue;
      std::string msg = "unknown key '" + key + "' in " + where;
      const std::string guess = nearest(key, allowed);
      if (!guess.empty()) msg += " (did you mean '" + guess + "'?)";
      else {
        msg += " (valid keys:";
        for (const auto& a : allowed) msg += " " + a;
        msg += ")";
      }
      fail(it->first, msg);
    }
  }

  YAML::Node require(const YAML::Node& map, const std::string& key, const std::string& where) const {
    const YAML::Node n = map[key];
    if (!n) fail(map, "missing key '" + key + "' in " + where);
    return n;
  }

  double number(const YAML::Node& n, const std::string& what) const {
    if (!n.IsScalar()) fail(n, "expected a number for " + what);
    double v = 0;
    try {
      v = n.as<double>();
    } catch (const YAML::Exception&) {
      fail(n, "expected a number for " + what + ", got '" + n.Scalar() + "'");
    }
    if (!std::isfinite(v)) fail(n, "expected a finite number for " + what + ", got '" + n.Scalar() + "'");
    return v;
  }

  double positive(const YAML::Node& n, const std::string& what) const {
    const double v = number(n, what);
    if (!(v > 0)) fail(n, what + " must be positive, got " + n.Scalar());
    return v;
  }

  double non_negative(const YAML::Node& n, const std::string& what) const {
    const double v = number(n, what);
    if (v < 0) fail(n, what + " must be zero or positive, got " + n.Scalar());
    return v;
  }

  std::int64_t integer(const YAML::Node& n, const std::string& what, std::int64_t lo, std::int64_t hi) const {
    if (!n.IsScalar()) fail(n, "expected an integer for " + what);
    long long v = 0;
    try {
      v = n.as<long long>();
    } catch (const YAML::Exception&) {
      fail(n, "expected an integer for " + what + ", got '" + n.Scalar() + "'");
    }
    if (v < lo || v > hi) {
      std::ostringstream s;
      s << what << " must be between " << lo << " and " << hi << ", got " << v;
      fail(n, s.str());
    }
    return v;
  }

  bool boolean(const YAML::Node& n, const std::string& what) const {
    if (!n.IsScalar()) fail(n, "expected true or false for " + what);
    try {
      return n.as<bool>();
    } catch (const YAML::Exception&) {
      fail(n, "expected true or false for " + what + ", got '" + n.Scalar() + "'");
    }
  }

  std::string text(const YAML::Node& n, const std::string& what) const {
    if (!n.IsScalar()) fail(n, "expected a string for " + what);
    return n.Scalar();
  }

  Vec3 vec3(const YAML::Node& n, const std::string& what) const {
    if (!n.IsSequence() || n.size() != 3) fail(n, "expected a list of three numbers [x, y, z] for " + what);
    return {number(n[0], what), number(n[1], what), number(n[2], what)};
  }

  std::array<int, 3> int3(const YAML::Node& n, const std::string& what, int lo, int hi) const {
    if (!n.IsSequence() || n.size() != 3) fail(n, "expected a list of three integers for " + what);
    std::array<int, 3> r{};
    for (int i = 0; i < 3; ++i) r[i] = static_cast<int>(integer(n[i], what, lo, hi));
    return r;
  }

  template <class E>
  E choice(const YAML::Node& n, const std::string& what, const std::vector<std::pair<std::string, E>>& options) const {
    const std::string v = text(n, what);
    std::vector<std::string> names;
    for (const auto& [name, e] : options) {
      if (name == v) return e;
      names.push_back(name);
    }
    std::string msg = "unknown " + what + " '" + v + "'";
    const std::string guess = nearest(v, names);
    if (!guess.empty()) msg += " (did you mean '" + guess + "'?)";
    msg += "; expected one of:";
    for (const auto& nm : names) msg += " " + nm;
    fail(n, msg);
  }

private:
  std::string file_;
};

void parse_simulation(const Reader& r, const YAML::Node& n, Simulation& sim) {
  r.check_keys(n, {"dt", "dt_safety", "dt_bound", "end_time", "steps", "gravity", "integrator", "output", "self_collisions",
                   "edge_contacts", "mutual_pairs", "split_objects", "split_detection", "split_parts", "contact_closure", "separation_speed", "checkpoint", "limits",
                   "rebalance"},
               "'simulation'");
  if (const auto dt = n["dt"]) {
    if (dt.IsScalar() && dt.Scalar() == "auto") {
      sim.dt_auto = true;
    } else {
      sim.dt_auto = false;
      sim.dt = r.positive(dt, "'dt' (seconds, or 'auto')");
    }
  }
  if (const auto s = n["dt_safety"]) {
    sim.dt_safety = r.positive(s, "'dt_safety'");
    if (sim.dt_safety > 1) r.fail(s, "'dt_safety' must be in (0, 1], got " + s.Scalar());
  }
  if (const auto b = n["dt_bound"])
    sim.dt_bound = r.choice<DtBound>(b, "dt_bound", {{"element", DtBound::element}, {"mesh", DtBound::mesh}});
  const auto end = n["end_time"];
  const auto steps = n["steps"];
  if (end && steps) r.fail(steps, "give either 'end_time' or 'steps' in 'simulation', not both");
  if (!end && !steps) r.fail(n, "missing key 'end_time' (or 'steps') in 'simulation'");
  if (end) sim.end_time = r.positive(end, "'end_time' (seconds)");
  if (steps) sim.steps = r.integer(steps, "'steps'", 1, std::int64_t{1} << 40);
  if (const auto g = n["gravity"]) sim.gravity = r.vec3(g, "'gravity' (m/s^2)");
  if (const auto i = n["integrator"])
    sim.integrator = r.choice<IntegratorKind>(i, "integrator",
                                              {{"verlet", IntegratorKind::verlet},
                                               {"symplectic_euler", IntegratorKind::symplectic_euler},
                                               {"implicit_euler", IntegratorKind::implicit_euler}});
  if (const auto sc = n["self_collisions"]) sim.self_collisions = r.boolean(sc, "'self_collisions'");
  if (const auto ec = n["edge_contacts"]) sim.edge_contacts = r.boolean(ec, "'edge_contacts'");
  if (const auto mp = n["mutual_pairs"]) sim.mutual_pairs = r.boolean(mp, "'mutual_pairs'");
  if (const auto so = n["split_objects"]) sim.split_objects = r.boolean(so, "'split_objects'");
  if (const auto sd = n["split_detection"]) sim.split_detection = r.boolean(sd, "'split_detection'");
  if (const auto sp = n["split_parts"])
    sim.split_parts = r.choice<SplitParts>(
        sp, "split_parts",
        {{"auto", SplitParts::automatic}, {"metis", SplitParts::metis}, {"bisection", SplitParts::bisection}});
  if (const auto cc = n["contact_closure"])
    sim.contact_closure = r.choice<ContactClosure>(cc, "contact_closure",
                                                   {{"local", ContactClosure::local}, {"coupled", ContactClosure::coupled}});
  if (const auto sp = n["separation_speed"])
    sim.separation_speed = r.positive(sp, "'separation_speed' (m/s, how fast overlapping bodies are pushed apart)");
  if (const auto o = n["output"]) {
    r.check_keys(o, {"directory", "every", "interval"}, "'simulation.output'");
    if (const auto d = o["directory"]) sim.output_dir = r.text(d, "'output.directory'");
    if (o["every"] && o["interval"]) r.fail(o["interval"], "give either 'every' (steps) or 'interval' (seconds) in 'output', not both");
    if (const auto e = o["every"]) sim.output_every = r.integer(e, "'output.every' (steps between frames)", 1, std::int64_t{1} << 40);
    if (const auto iv = o["interval"]) sim.output_interval = r.positive(iv, "'output.interval' (seconds between frames)");
  }
  if (const auto c = n["checkpoint"]) {
    r.check_keys(c, {"every", "minutes", "keep"}, "'simulation.checkpoint'");
    if (const auto e = c["every"]) sim.checkpoint_every = r.integer(e, "'checkpoint.every' (steps between checkpoints)", 1, std::int64_t{1} << 40);
    if (const auto m = c["minutes"]) sim.checkpoint_minutes = r.positive(m, "'checkpoint.minutes' (wall minutes between checkpoints)");
    if (const auto k = c["keep"]) sim.checkpoint_keep = r.integer(k, "'checkpoint.keep' (checkpoints kept)", 1, 1000);
  }
  if (const auto rb = n["rebalance"]) {
    r.check_keys(rb, {"every", "max_imbalance", "max_cross_fraction", "weights"}, "'simulation.rebalance'");
    if (const auto e = rb["every"])
      sim.rebalance_every = r.integer(e, "'rebalance.every' (steps between checks, 0: never)", 0, std::int64_t{1} << 40);
    if (const auto m = rb["max_imbalance"]) {
      sim.rebalance_max_imbalance = r.positive(m, "'rebalance.max_imbalance' (max/mean of the ranks' work)");
      if (sim.rebalance_max_imbalance < 1) r.fail(m, "'rebalance.max_imbalance' must be at least 1, got " + m.Scalar());
    }
    if (const auto f = rb["max_cross_fraction"]) {
      sim.rebalance_max_cross_fraction = r.positive(f, "'rebalance.max_cross_fraction'");
      if (sim.rebalance_max_cross_fraction > 1) r.fail(f, "'rebalance.max_cross_fraction' must be in (0, 1], got " + f.Scalar());
    }
    if (const auto w = rb["weights"])
      sim.rebalance_weights = r.choice<RebalanceWeights>(w, "rebalance.weights",
                                                         {{"measured", RebalanceWeights::measured}, {"tets", RebalanceWeights::tets}});
  }
  if (const auto l = n["limits"]) {
    r.check_keys(l, {"max_speed", "max_inverted_fraction"}, "'simulation.limits'");
    if (const auto v = l["max_speed"]) sim.max_speed = r.positive(v, "'limits.max_speed' (m/s)");
    if (const auto f = l["max_inverted_fraction"]) {
      sim.max_inverted_fraction = r.positive(f, "'limits.max_inverted_fraction'");
      if (sim.max_inverted_fraction > 1) r.fail(f, "'limits.max_inverted_fraction' must be in (0, 1], got " + f.Scalar());
    }
  }
}

Material parse_material(const Reader& r, const YAML::Node& n) {
  r.check_keys(n, {"name", "model", "young", "poisson", "density", "damping"}, "a material");
  Material m;
  m.name = r.text(r.require(n, "name", "a material"), "'name'");
  const std::string where = "material '" + m.name + "'";
  if (const auto model = n["model"]) {
    std::vector<std::pair<std::string, ModelKind>> laws;
    for (int k = 0; k < kModelKinds; ++k) laws.emplace_back(kModelNames[k], static_cast<ModelKind>(k));
    m.model = r.choice<ModelKind>(model, "model", laws);
  }
  m.young = r.positive(r.require(n, "young", where), "'young' (Young's modulus, Pa) of " + where);
  const auto nu = r.require(n, "poisson", where);
  m.poisson = r.number(nu, "'poisson' of " + where);
  if (!(m.poisson > -1.0 && m.poisson < 0.5))
    r.fail(nu, "'poisson' of " + where + " must lie in (-1, 0.5), got " + nu.Scalar());
  m.density = r.positive(r.require(n, "density", where), "'density' (kg/m^3) of " + where);
  if (const auto d = n["damping"]) {
    r.check_keys(d, {"mass", "stiffness"}, "'damping' of " + where);
    if (d["mass"]) m.damping_mass = r.non_negative(d["mass"], "'damping.mass' (1/s) of " + where);
    if (d["stiffness"]) m.damping_stiffness = r.non_negative(d["stiffness"], "'damping.stiffness' (s) of " + where);
  }
  return m;
}

Friction parse_coefficients(const Reader& r, const YAML::Node& n, const std::string& where) {
  Friction f;
  f.mu_static = r.non_negative(r.require(n, "static", where), "'static' friction of " + where);
  f.mu_kinetic = n["kinetic"] ? r.non_negative(n["kinetic"], "'kinetic' friction of " + where) : f.mu_static;
  if (f.mu_kinetic > f.mu_static)
    r.fail(n["kinetic"], "'kinetic' friction of " + where + " exceeds 'static' (expected kinetic <= static)");
  return f;
}

int material_index(const Reader& r, const YAML::Node& n, const std::vector<Material>& mats) {
  const std::string name = r.text(n, "material name");
  std::vector<std::string> names;
  for (std::size_t i = 0; i < mats.size(); ++i) {
    if (mats[i].name == name) return static_cast<int>(i);
    names.push_back(mats[i].name);
  }
  std::string msg = "unknown material '" + name + "'";
  const std::string guess = nearest(name, names);
  if (!guess.empty()) msg += " (did you mean '" + guess + "'?)";
  msg += "; materials defined:";
  for (const auto& nm : names) msg += " " + nm;
  r.fail(n, msg);
}

void parse_friction(const Reader& r, const YAML::Node& n, Scene& scene) {
  r.check_keys(n, {"default", "pairs"}, "'friction'");
  if (const auto d = n["default"]) {
    r.check_keys(d, {"static", "kinetic"}, "'friction.default'");
    scene.default_friction = parse_coefficients(r, d, "'friction.default'");
  }
  const std::size_t nm = scene.materials.size();
  scene.friction.assign(nm, std::vector<Friction>(nm, scene.default_friction));
  if (const auto pairs = n["pairs"]) {
    if (!pairs.IsSequence()) r.fail(pairs, "'friction.pairs' must be a list");
    for (const auto& p : pairs) {
      r.check_keys(p, {"materials", "static", "kinetic"}, "a friction pair");
      const auto ms = r.require(p, "materials", "a friction pair");
      if (!ms.IsSequence() || ms.size() != 2) r.fail(ms, "expected two material names [a, b] in 'materials'");
      const int a = material_index(r, ms[0], scene.materials);
      const int b = material_index(r, ms[1], scene.materials);
      const Friction f = parse_coefficients(r, p, "friction pair " + scene.materials[a].name + "/" + scene.materials[b].name);
      scene.friction[a][b] = scene.friction[b][a] = f;
    }
  }
}

/// The scene's size so far against its SceneLimits. Sizes are doubles so that products of
/// counts from the file (copies times tets) cannot overflow before they are compared.
class SizeBudget {
public:
  explicit SizeBudget(const SceneLimits& limits) : limits_(limits) {}

  /// Throws at `at` unless `copies` more objects of `vertices` and `tets` each fit.
  void check(const Reader& r, const YAML::Node& at, const std::string& what, double copies, double vertices,
             double tets) const {
    if (objects_ + copies > static_cast<double>(limits_.max_objects)) {
      std::ostringstream s;
      s << what << " makes " << copies << " objects; with the " << objects_ << " before it that is more than the "
        << limits_.max_objects << " objects a scene can hold";
      r.fail(at, s.str());
    }
    check_mesh(r, at, what, copies, vertices, tets);
  }
  /// The vertices and tets alone (a single-copy entry's mesh, counted once every rank
  /// knows it: parse_objects).
  void check_mesh(const Reader& r, const YAML::Node& at, const std::string& what, double copies, double vertices,
                  double tets) const {
    if (vertices_ + copies * vertices > static_cast<double>(limits_.max_vertices) ||
        tets_ + copies * tets > static_cast<double>(limits_.max_tets)) {
      std::ostringstream s;
      s.precision(15);
      s << what << " gives " << copies * vertices << " vertices and " << copies * tets << " tets";
      if (copies != 1) s << " (" << copies << " copies of " << vertices << " and " << tets << ")";
      s << "; with the " << vertices_ << " and " << tets_ << " of the objects counted before it that is more than the "
        << limits_.max_vertices << " vertices and " << limits_.max_tets << " tets a scene can hold";
      r.fail(at, s.str());
    }
  }
  void add(double copies, double vertices, double tets) {
    objects_ += copies;
    add_mesh(copies, vertices, tets);
  }
  void add_mesh(double copies, double vertices, double tets) {
    vertices_ += copies * vertices;
    tets_ += copies * tets;
  }

private:
  SceneLimits limits_;
  double objects_ = 0, vertices_ = 0, tets_ = 0;
};

/// Vertex and tet counts of a disk/ball layout with `across` cells across (primitives.hpp).
struct OGridSize {
  double n, m;
  explicit OGridSize(double across) {
    m = std::max(1.0, std::floor((across + 2) / 4));
    n = std::max(1.0, across - 2 * m);
  }
};

std::function<TetMesh()> parse_primitive(const Reader& r, const YAML::Node& n, const std::string& where, const SizeBudget& budget) {
  r.expect_map(n, "'primitive' of " + where);
  const auto type_node = r.require(n, "type", "'primitive' of " + where);
  enum class P { box, plate, cylinder, sphere, torus };
  const P type = r.choice<P>(type_node, "primitive type",
                             {{"box", P::box}, {"plate", P::plate}, {"membrane", P::plate},
                              {"cylinder", P::cylinder}, {"sphere", P::sphere}, {"torus", P::torus}});
  const std::string pw = "primitive '" + type_node.Scalar() + "' of " + where;
  constexpr int kMaxCells = 4096;
  auto res = [&](const char* key, int dflt, int lo) {
    return n[key] ? static_cast<int>(r.integer(n[key], std::string("'") + key + "' of " + pw, lo, kMaxCells)) : dflt;
  };
  // A cell count derived from a ratio of lengths (when not given), checked in double
  // before it becomes an int: a thin torus or a needle-like cylinder could ask for any number.
  auto derived = [&](const char* key, double cells, int lo, const char* from) {
    if (n[key]) return res(key, lo, lo);
    if (!(cells <= kMaxCells)) {
      std::ostringstream s;
      s.precision(15);
      s << from << " of " << pw << " give " << cells << " cells for '" << key << "' (expected at most " << kMaxCells
        << "); give '" << key << "' explicitly";
      r.fail(n, s.str());
    }
    return std::max(lo, static_cast<int>(std::lround(cells)));
  };
  // Checked before the mesh is built (counts in primitives.hpp).
  auto fits = [&](double vertices, double tets) { budget.check(r, n, pw, 1, vertices, tets); };
  try {
    switch (type) {
      case P::box: {
        r.check_keys(n, {"type", "size", "cells", "resolution"}, pw);
        const Vec3 size = r.vec3(r.require(n, "size", pw), "'size' of " + pw);
        for (double s : size)
          if (!(s > 0)) r.fail(n["size"], "'size' of " + pw + " must be positive in every direction");
        std::array<int, 3> cells{};
        if (n["cells"]) {
          if (n["resolution"]) r.fail(n["resolution"], "give either 'cells' or 'resolution' for " + pw);
          cells = r.int3(n["cells"], "'cells' of " + pw, 1, 4096);
        } else {
          // resolution = cells along the longest side; the others keep cells near cubic
          const int k = res("resolution", 4, 1);
          const double lmax = std::max({size[0], size[1], size[2]});
          for (int d = 0; d < 3; ++d) cells[d] = std::max(1, static_cast<int>(std::lround(k * size[d] / lmax)));
        }
        const double cx = cells[0], cy = cells[1], cz = cells[2];
        fits((cx + 1) * (cy + 1) * (cz + 1), 6 * cx * cy * cz);
        return [=] { return make_box(size[0], size[1], size[2], cells[0], cells[1], cells[2]); };
      }
      case P::plate: {
        r.check_keys(n, {"type", "size", "thickness", "cells", "layers"}, pw);
        const auto sz = r.require(n, "size", pw);
        if (!sz.IsSequence() || sz.size() != 2) r.fail(sz, "expected [lx, ly] for 'size' of " + pw);
        const double lx = r.positive(sz[0], "'size' of " + pw), ly = r.positive(sz[1], "'size' of " + pw);
        const double t = r.positive(r.require(n, "thickness", pw), "'thickness' of " + pw);
        int nx = 10, ny = 10;
        if (const auto c = n["cells"]) {
          if (!c.IsSequence() || c.size() != 2) r.fail(c, "expected [nx, ny] for 'cells' of " + pw);
          nx = static_cast<int>(r.integer(c[0], "'cells' of " + pw, 1, 4096));
          ny = static_cast<int>(r.integer(c[1], "'cells' of " + pw, 1, 4096));
        }
        const int layers = res("layers", 1, 1);
        fits((nx + 1.0) * (ny + 1.0) * (layers + 1.0), 6.0 * nx * ny * layers);
        return [=] { return make_box(lx, ly, t, nx, ny, layers); };
      }
      case P::cylinder: {
        r.check_keys(n, {"type", "radius", "height", "resolution", "axial"}, pw);
        const double rad = r.positive(r.require(n, "radius", pw), "'radius' of " + pw);
        const double h = r.positive(r.require(n, "height", pw), "'height' of " + pw);
        const int k = res("resolution", 3, 1);
        const int ax = derived("axial", k * h / rad, 1, "'resolution' * 'height' / 'radius'");
        const OGridSize g(2.0 * k);
        fits(((g.n + 1) * (g.n + 1) + 4 * g.n * g.m) * (ax + 1.0), 6 * (g.n * g.n + 4 * g.n * g.m) * ax);
        return [=] { return make_cylinder(rad, h, k, ax); };
      }
      case P::sphere: {
        r.check_keys(n, {"type", "radius", "resolution"}, pw);
        const double rad = r.positive(r.require(n, "radius", pw), "'radius' of " + pw);
        const int k = res("resolution", 6, 2);
        const OGridSize g(k);
        fits((g.n + 1) * (g.n + 1) * (g.n + 1) + (6 * g.n * g.n + 2) * g.m, 6 * (g.n * g.n * g.n + 6 * g.n * g.n * g.m));
        return [=] { return make_sphere(rad, k); };
      }
      case P::torus: {
        r.check_keys(n, {"type", "major_radius", "minor_radius", "resolution", "around"}, pw);
        const double R = r.positive(r.require(n, "major_radius", pw), "'major_radius' of " + pw);
        const double a = r.positive(r.require(n, "minor_radius", pw), "'minor_radius' of " + pw);
        if (!(a < R)) r.fail(n["minor_radius"], "'minor_radius' of " + pw + " must be smaller than 'major_radius'");
        const int k = res("resolution", 4, 2);
        // cells around the ring so that they are about as long as across the tube
        const int around = derived("around", M_PI * R * k / a, 3, "pi * 'major_radius' * 'resolution' / 'minor_radius'");
        const OGridSize g(k);
        fits(((g.n + 1) * (g.n + 1) + 4 * g.n * g.m) * around, 6 * (g.n * g.n + 4 * g.n * g.m) * around);
        return [=] { return make_torus(R, a, around, k); };
      }
    }
  } catch (const InputError& e) {
    if (!e.file().empty()) throw;
    r.fail(n, e.detail());
  }
  r.fail(n, "unsupported primitive");
}

double max_tet_frequency(const TetMesh& m, const Material& mat);  // below

/// The larger of two frequencies, NaN when either is (std::max alone would drop a NaN).
double max_or_nan(double a, double b) {
  return std::isnan(a) || std::isnan(b) ? std::numeric_limits<double>::quiet_NaN() : std::max(a, b);
}

/// The 12 coordinates of tet t's corners (corner after corner) from mesh m into X.
void tet_corners(const TetMesh& m, std::int64_t t, double* X) {
  for (std::size_t k = 0; k < 4; ++k) {
    const double* p = &m.points[3 * static_cast<std::size_t>(m.tets[4 * static_cast<std::size_t>(t) + k])];
    X[3 * k] = p[0];
    X[3 * k + 1] = p[1];
    X[3 * k + 2] = p[2];
  }
}

/// Highest tet_max_frequency of tets 0 .. nt - 1, whose corners `corners(t, X)` writes;
/// NaN when any tet's is NaN, so that the caller can reject it (std::max alone would drop
/// a NaN). A maximum is exact in any order: the result does not depend on the threads, nor
/// on how the tets are cut into pieces.
template <class Corners>
double max_frequency(std::ptrdiff_t nt, const Material& mat, const Corners& corners) {
  double wmax = 0;
  bool nan = false;
#pragma omp parallel for schedule(static) reduction(max : wmax) reduction(|| : nan) if (nt > 1024)
  for (std::ptrdiff_t t = 0; t < nt; ++t) {
    double X[12];
    corners(t, X);
    const double w = tet_max_frequency(X, mat);
    nan = nan || std::isnan(w);
    wmax = std::max(wmax, w);
  }
  return nan ? std::numeric_limits<double>::quiet_NaN() : wmax;
}

/// Words per entry of what parse_objects' ranks share of a single-copy entry's mesh: made
/// (0: failed, 1: made), warnings, then vertices, tets, triangles, the box (6 doubles),
/// digest, element frequency, mesh bound and its estimate, each a 64-bit word sent as two
/// exact 32-bit halves, so that a sum over the ranks (the others add zeros) gives every
/// value to the bit (NaN and -0 included).
constexpr std::size_t kMadeWords = 2 + 2 * (3 + 6 + 1 + 3);

void put_word(std::vector<double>& v, std::size_t at, std::uint64_t w) {
  v[at] = static_cast<double>(w >> 32);
  v[at + 1] = static_cast<double>(w & 0xffffffffu);
}
std::uint64_t get_word(const std::vector<double>& v, std::size_t at) {
  return (static_cast<std::uint64_t>(v[at]) << 32) | static_cast<std::uint64_t>(v[at + 1]);
}
void put_real(std::vector<double>& v, std::size_t at, double x) {
  std::uint64_t w;
  std::memcpy(&w, &x, sizeof w);
  put_word(v, at, w);
}
double get_real(const std::vector<double>& v, std::size_t at) {
  const std::uint64_t w = get_word(v, at);
  double x;
  std::memcpy(&x, &w, sizeof x);
  return x;
}

/// A single-copy entry whose mesh no multi-copy entry uses (a file that only single-copy
/// entries name, or a primitive): one rank makes it (reads the file, once per rank for
/// all the entries it makes from it, or generates it), the rank of its object's index k
/// (k % parts), places it, measures it and computes its frequencies; the others learn
/// those from that rank and make the mesh only if they come to need it (docs/architecture.md,
/// "Who reads which mesh file").
struct MadeOnce {
  EntrySpec spec;                     ///< without its mesh
  YAML::Node node;
  std::string where;
  std::function<TetMesh(MeshReport*)> make;  ///< the mesh in its own coordinates, errors at the entry
  std::size_t object = 0;             ///< its slot in scene.objects
  bool mine = false;                  ///< made here
  std::exception_ptr error;           ///< making or placing it here failed
};

/// What the objects' parse learnt that load_scene would otherwise compute from every mesh:
/// the element frequency of each single-copy movable object and, with the mesh bound, its
/// mesh's bound (by entry).
struct ParsedObjects {
  std::map<std::size_t, double> frequency;
  std::map<int, MeshFrequency> mesh_bound;
};

ParsedObjects parse_objects(const Reader& r, const YAML::Node& list, Scene& scene, const std::filesystem::path& dir,
                            const SceneLimits& limits) {
  SizeBudget budget(limits);
  if (!list.IsSequence() || list.size() == 0) r.fail(list, "'objects' must be a non-empty list of objects");
  auto mesh_key = [&dir](const std::string& rel) {
    const std::filesystem::path p = std::filesystem::path(rel).is_absolute() ? std::filesystem::path(rel) : dir / rel;
    return p.lexically_normal().string();
  };
  // Which entries name each mesh file. A file that only single-copy entries name is read
  // by the ranks that make them (MadeOnce; its reading's warnings belong to the first
  // entry that names it); one that a multi-copy entry names is read once per rank and
  // shared by its entries.
  struct FileUse {
    int entries = 0;
    int first = -1;       ///< the first entry naming it
    bool copies = false;  ///< a multi-copy entry names it
  };
  std::map<std::string, FileUse> uses;
  for (std::size_t e = 0; e < list.size(); ++e) {
    const YAML::Node n = list[e];
    if (!n.IsMap() || !n["mesh"] || !n["mesh"].IsScalar()) continue;
    FileUse& u = uses[mesh_key(n["mesh"].Scalar())];
    ++u.entries;
    if (u.first < 0) u.first = static_cast<int>(e);
    u.copies = u.copies || static_cast<bool>(n["instances"]);
  }
  const bool shared = limits.parts > 1 && static_cast<bool>(limits.sum);
  std::map<std::string, std::pair<TetMesh, MeshReport>> mesh_cache;  // a file instanced many times is read once
  std::vector<std::vector<std::string>> warnings(list.size());      // of reading each entry's mesh
  std::vector<PendingRandom> pending;  // random entries, placed after the loop
  std::vector<YAML::Node> pending_nodes;
  std::vector<MadeOnce> made;
  ParsedObjects parsed;
  // The files that multi-copy entries name, each read by one rank (the k-th in order of
  // the entries by part k % parts) and broadcast with its warnings: each rank reads its
  // files first, then the broadcasts go in order. A file its rank could not read comes as
  // one byte 0 (`unread`: file -> that rank); every rank then reads it at its first entry
  // and reports the error there, as one rank alone would.
  std::set<std::string> received;
  std::map<std::string, int> unread;
  if (shared && limits.broadcast) {
    std::vector<std::pair<int, std::string>> files;  // (first entry, file)
    for (const auto& [key, u] : uses)
      if (u.copies) files.emplace_back(u.first, key);
    std::sort(files.begin(), files.end());
    std::vector<std::vector<char>> bytes(files.size());
    const auto parts = static_cast<std::size_t>(limits.parts);
    for (std::size_t j = 0; j < files.size(); ++j) {
      if (static_cast<int>(j % parts) != limits.part) continue;
      try {
        MeshReport rep;
        const TetMesh m = read_mesh(files[j].second, &rep);
        bytes[j].assign(1, 1);
        append_mesh_bytes(bytes[j], m, &rep);
      } catch (const std::exception&) {
        bytes[j].assign(1, 0);
      }
    }
    for (std::size_t j = 0; j < files.size(); ++j) {
      const std::string& key = files[j].second;
      const int root = static_cast<int>(j % parts);
      limits.broadcast(bytes[j], root);
      if (!bytes[j].empty() && bytes[j][0] == 1) {
        std::size_t at = 1;
        MeshReport rep;
        TetMesh m = take_mesh_bytes(bytes[j], at, &rep);
        mesh_cache.emplace(key, std::make_pair(std::move(m), std::move(rep)));
        received.insert(key);
      } else {
        unread[key] = root;
      }
      std::vector<char>().swap(bytes[j]);
    }
  }
  auto place = [&](const EntrySpec& spec, const YAML::Node& n, std::vector<SceneObject>& objects) {
    try {
      const std::size_t before = pending.size();
      instantiate(spec, objects, limits.hold_copy_meshes, &pending);
      if (pending.size() > before) pending_nodes.push_back(n);
    } catch (const InputError& e) {
      if (!e.file().empty()) throw;
      r.fail(n, e.detail());
    }
  };
  // Whether the element frequency of a made mesh is computed by all ranks together
  // (SceneLimits::scatter): decided alike on every rank, from its tet count.
  auto spread = [&](const MadeOnce& d, std::uint64_t tets) {
    return shared && limits.scatter && !d.spec.kinematic && scene.sim.dt_bound == DtBound::element &&
           static_cast<std::int64_t>(tets) >= limits.spread_tets;
  };
  // The spread meshes' frequencies, in the order of `made`: their makers send out their
  // tets' corners round by round, each rank takes the highest frequency of its pieces, and
  // one sum gives every rank every part's highest (each part writes its own slot; the
  // others add zeros), whose maximum is exactly the one rank's value.
  auto spread_frequencies = [&] {
    std::vector<std::size_t> wide;  // into `made`
    for (std::size_t i = 0; i < made.size(); ++i)
      if (spread(made[i], scene.shape(made[i].object).tets)) wide.push_back(i);
    if (wide.empty()) return;
    const auto parts = static_cast<std::size_t>(limits.parts), part = static_cast<std::size_t>(limits.part);
    const std::int64_t round = std::max<std::int64_t>(limits.spread_round_tets, 1);
    std::vector<double> highest(wide.size() * parts, 0.0);
    for (std::size_t j = 0; j < wide.size(); ++j) {
      const MadeOnce& d = made[wide[j]];
      const Material& mat = scene.materials[static_cast<std::size_t>(d.spec.material)];
      const auto nt = static_cast<std::int64_t>(scene.shape(d.object).tets);
      const int root = static_cast<int>(d.object % parts);
      double w = 0;
      for (std::int64_t s = 0; s < nt; s += round) {
        const std::int64_t n = std::min(round, nt - s);
        const auto first = [&](std::size_t k) { return s + n * static_cast<std::int64_t>(k) / static_cast<std::int64_t>(parts); };
        std::vector<int> counts(parts);
        for (std::size_t k = 0; k < parts; ++k) counts[k] = static_cast<int>(12 * (first(k + 1) - first(k)));
        std::vector<double> all;
        if (d.mine) {
          const TetMesh& m = scene.objects[d.object].mesh;
          all.resize(static_cast<std::size_t>(12 * n));
          for (std::int64_t t = 0; t < n; ++t) tet_corners(m, s + t, &all[static_cast<std::size_t>(12 * t)]);
        }
        const std::vector<double> piece = limits.scatter(all, counts, root);
        const double wp = max_frequency(static_cast<std::ptrdiff_t>(piece.size() / 12), mat, [&piece](std::ptrdiff_t t, double X[12]) {
          std::copy_n(&piece[12 * static_cast<std::size_t>(t)], 12, X);
        });
        w = max_or_nan(w, wp);
      }
      highest[j * parts + part] = w;
    }
    limits.sum(highest);
    for (std::size_t j = 0; j < wide.size(); ++j) {
      double w = 0;
      for (std::size_t k = 0; k < parts; ++k) w = max_or_nan(w, highest[j * parts + k]);
      parsed.frequency[made[wide[j]].object] = w;
    }
  };
  // The ranks share what they learnt of the entries they made. With `errors_only`, only
  // whether each was made (on the way out with an error of the scene file: the first
  // entry in scene order that could not be made is reported instead, as one rank would).
  // Collective: every rank reaches it at the same point, for errors of the YAML are
  // found alike on every rank.
  auto settle = [&](bool errors_only) {
    if (made.empty()) return;
    std::vector<double> v(made.size() * kMadeWords, 0.0);
    for (std::size_t i = 0; i < made.size(); ++i) {
      const MadeOnce& d = made[i];
      const std::size_t at = i * kMadeWords;
      if (!d.mine || d.error) continue;
      v[at] = 1;
      v[at + 1] = static_cast<double>(warnings[static_cast<std::size_t>(d.spec.index)].size());
      if (errors_only) continue;
      const SceneObject& o = scene.objects[d.object];
      const ObjectShape& sh = scene.shape(d.object);
      put_word(v, at + 2, sh.vertices);
      put_word(v, at + 4, sh.tets);
      put_word(v, at + 6, sh.triangles);
      for (int c = 0; c < 3; ++c) {
        put_real(v, at + 8 + 2 * c, sh.box.lo[c]);
        put_real(v, at + 14 + 2 * c, sh.box.hi[c]);
      }
      put_word(v, at + 20, o.placement.base->digest());
      if (o.kinematic() || spread(d, sh.tets)) continue;  // a spread mesh's frequency: below
      const Material& mat = scene.materials[static_cast<std::size_t>(o.material)];
      const double w = max_tet_frequency(o.mesh, mat);
      put_real(v, at + 22, w);
      if (scene.sim.dt_bound == DtBound::mesh && w > 0 && w < std::numeric_limits<double>::infinity()) {
        const MeshFrequency f = mesh_max_frequency(o.mesh, mat, w);
        put_real(v, at + 24, f.omega);
        put_real(v, at + 26, f.estimate);
      }
    }
    if (shared) limits.sum(v);
    for (std::size_t i = 0; i < made.size(); ++i) {
      MadeOnce& d = made[i];
      if (v[i * kMadeWords] != 0) continue;
      // The first entry that could not be made: its rank's error, which every other rank
      // finds again by making it (the same message, as if read here).
      if (d.error) std::rethrow_exception(d.error);
      std::vector<SceneObject> scratch;
      d.spec.mesh = d.make(nullptr);
      place(d.spec, d.node, scratch);
      r.fail(d.node, d.where + ": its mesh could not be made by the rank that read it, but was here (did '" +
                         d.spec.source + "' change while the scene was read?)");
    }
    if (errors_only) return;
    for (std::size_t i = 0; i < made.size(); ++i) {
      MadeOnce& d = made[i];
      const std::size_t at = i * kMadeWords;
      ObjectShape sh;
      sh.vertices = get_word(v, at + 2);
      sh.tets = get_word(v, at + 4);
      sh.triangles = get_word(v, at + 6);
      for (int c = 0; c < 3; ++c) {
        sh.box.lo[c] = get_real(v, at + 8 + 2 * c);
        sh.box.hi[c] = get_real(v, at + 14 + 2 * c);
      }
      budget.check_mesh(r, d.node, d.where, 1, static_cast<double>(sh.vertices), static_cast<double>(sh.tets));
      budget.add_mesh(1, static_cast<double>(sh.vertices), static_cast<double>(sh.tets));
      if (!d.mine) {
        scene.objects[d.object] = single_made_elsewhere(d.spec, get_word(v, at + 20), sh);
        // Its reading warned on the rank that read it: the words again, from the file.
        if (v[at + 1] != 0) {
          MeshReport rep;
          (void)d.make(&rep);
          warnings[static_cast<std::size_t>(d.spec.index)] = rep.warnings;
        }
      }
      if (shared) scene.objects[d.object].maker = static_cast<int>(d.object % static_cast<std::size_t>(limits.parts));
      if (d.spec.kinematic || spread(d, sh.tets)) continue;
      const double w = get_real(v, at + 22);
      parsed.frequency[d.object] = w;
      if (scene.sim.dt_bound == DtBound::mesh && w > 0 && w < std::numeric_limits<double>::infinity()) {
        MeshFrequency f;
        f.omega = get_real(v, at + 24);
        f.element = w;
        f.estimate = get_real(v, at + 26);
        parsed.mesh_bound[d.spec.index] = f;
      }
    }
    spread_frequencies();
  };

  int entry = 0;
  for (const auto& n : list) {
    try {
      ++entry;
      r.check_keys(n, {"name", "material", "mesh", "primitive", "transform", "velocity", "kinematic", "fixed", "motion", "instances"},
                   "an object");
      EntrySpec spec;
      spec.index = entry - 1;
      spec.name = n["name"] ? r.text(n["name"], "'name'") : "object" + std::to_string(entry);
      const std::string where = "object '" + spec.name + "'";
      spec.material = material_index(r, r.require(n, "material", where), scene.materials);
      if (n["mesh"] && n["primitive"]) r.fail(n["primitive"], where + " has both 'mesh' and 'primitive'; give one");
      std::string key;                                 // its mesh file
      std::function<TetMesh(MeshReport*)> make;        // its mesh: the file read, or the primitive generated
      if (n["mesh"]) {
        const std::string rel = r.text(n["mesh"], "'mesh'");
        const std::filesystem::path p = std::filesystem::path(rel).is_absolute() ? std::filesystem::path(rel) : dir / rel;
        key = mesh_key(rel);
        // Looked up by every rank for every entry (the ranks read different files, so
        // their caches differ). The error_code overload: a name the file system refuses
        // (too long, a component that is not a directory) is the scene's mistake, not an
        // exception.
        std::error_code ec;
        const bool there = received.count(key) || std::filesystem::exists(p, ec);  // a broadcast file was there
        if (ec)
          r.fail(n["mesh"], "cannot look up mesh file '" + key + "' of " + where + ": " + ec.message() +
                                " (expected the path of a .msh or .node mesh file)");
        if (!there) r.fail(n["mesh"], "mesh file '" + key + "' of " + where + " does not exist");
        spec.remake = [key] { return read_mesh(key); };  // its warnings were given once, when first read
        make = [key](MeshReport* rep) { return read_mesh(key, rep); };
        spec.source = rel;
      } else if (n["primitive"]) {
        spec.remake = parse_primitive(r, n["primitive"], where, budget);
        make = [&r, node = n["primitive"], generate = spec.remake](MeshReport*) {
          try {
            return generate();
          } catch (const InputError& e) {
            if (!e.file().empty()) throw;
            r.fail(node, e.detail());
          }
        };
        spec.source = "primitive " + n["primitive"]["type"].Scalar();
      } else {
        r.fail(n, where + " needs a 'mesh' file or a 'primitive'");
      }
      if (const auto t = n["transform"]) {
        r.check_keys(t, {"translate", "rotate", "scale"}, "'transform' of " + where);
        if (t["translate"]) spec.translate = r.vec3(t["translate"], "'translate'");
        if (const auto s = t["scale"]) {
          if (s.IsSequence()) {
            spec.scale = r.vec3(s, "'scale'");
            for (double c : spec.scale)
              if (!(c > 0)) r.fail(s, "'scale' must be positive in every direction");
          } else {
            const double c = r.positive(s, "'scale'");
            spec.scale = {c, c, c};
          }
        }
        if (const auto rot = t["rotate"]) {
          if (rot.IsSequence()) {
            const Vec3 e = r.vec3(rot, "'rotate' (degrees about x, y, z)");
            spec.rotation = rotation_xyz_degrees(e);
          } else {
            r.check_keys(rot, {"axis", "angle"}, "'rotate' of " + where);
            const Vec3 axis = r.vec3(r.require(rot, "axis", "'rotate'"), "'rotate.axis'");
            if (std::hypot(axis[0], axis[1], axis[2]) == 0) r.fail(rot["axis"], "'rotate.axis' must not be zero");
            spec.rotation = rotation_axis_angle(axis, r.number(r.require(rot, "angle", "'rotate'"), "'rotate.angle' (degrees)"));
          }
        }
      }
      if (n["velocity"]) spec.velocity = r.vec3(n["velocity"], "'velocity' (m/s)");
      if (n["kinematic"]) spec.kinematic = r.boolean(n["kinematic"], "'kinematic'");
      if (const auto f = n["fixed"]) {
        auto one = [&](const YAML::Node& b) {
          r.check_keys(b, {"min", "max"}, "'fixed' box of " + where);
          Box box{r.vec3(r.require(b, "min", "'fixed'"), "'fixed.min'"), r.vec3(r.require(b, "max", "'fixed'"), "'fixed.max'")};
          for (int d = 0; d < 3; ++d)
            if (box.lo[d] > box.hi[d]) r.fail(b, "'fixed' box of " + where + " has min > max");
          spec.fixed.push_back(box);
        };
        if (f.IsSequence())
          for (const auto& b : f) one(b);
        else
          one(f);
      }
      if (const auto mo = n["motion"]) {
        r.check_keys(mo, {"velocity", "start", "stop"}, "'motion' of " + where);
        spec.motion.velocity = r.vec3(r.require(mo, "velocity", "'motion'"), "'motion.velocity' (m/s)");
        if (mo["start"]) spec.motion.start = r.number(mo["start"], "'motion.start' (s)");
        if (spec.motion.start < 0) r.fail(mo["start"], "'motion.start' must be >= 0 (seconds)");
        if (mo["stop"]) {
          spec.motion.stop = r.number(mo["stop"], "'motion.stop' (s)");
          if (!(spec.motion.stop > spec.motion.start)) r.fail(mo["stop"], "'motion.stop' must be later than 'motion.start'");
        }
        if (!spec.kinematic && spec.fixed.empty())
          r.fail(mo, "'motion' of " + where + " moves its fixed vertices, but it has none: add 'kinematic: true' or 'fixed' boxes");
      }
      if (const auto inst = n["instances"]) {
        r.check_keys(inst, {"grid", "random"}, "'instances' of " + where);
        if (inst["grid"] && inst["random"]) r.fail(inst, "give either 'grid' or 'random' in 'instances', not both");
        if (const auto g = inst["grid"]) {
          r.check_keys(g, {"count", "spacing"}, "'instances.grid'");
          spec.grid_count = r.int3(r.require(g, "count", "'instances.grid'"), "'grid.count'", 1, 100000);
          spec.grid_spacing = r.vec3(r.require(g, "spacing", "'instances.grid'"), "'grid.spacing' (m)");
          spec.instancing = EntrySpec::Instancing::grid;
        } else if (const auto rnd = inst["random"]) {
          r.check_keys(rnd, {"count", "region", "seed", "rotate"}, "'instances.random'");
          spec.random_count = static_cast<int>(r.integer(r.require(rnd, "count", "'instances.random'"), "'random.count'", 1, 1000000));
          const auto reg = r.require(rnd, "region", "'instances.random'");
          r.check_keys(reg, {"min", "max"}, "'random.region'");
          spec.region = {r.vec3(r.require(reg, "min", "'region'"), "'region.min'"), r.vec3(r.require(reg, "max", "'region'"), "'region.max'")};
          for (int d = 0; d < 3; ++d)
            if (spec.region.lo[d] > spec.region.hi[d]) r.fail(reg, "'random.region' has min > max");
          spec.seed = rnd["seed"] ? static_cast<std::uint64_t>(r.integer(rnd["seed"], "'random.seed'", 0, std::numeric_limits<std::int64_t>::max())) : 1;
          spec.random_rotate = rnd["rotate"] ? r.boolean(rnd["rotate"], "'random.rotate'") : false;
          spec.instancing = EntrySpec::Instancing::random;
        }
      }
      double copies = 1;
      if (spec.instancing == EntrySpec::Instancing::grid)
        copies = static_cast<double>(spec.grid_count[0]) * spec.grid_count[1] * spec.grid_count[2];
      else if (spec.instancing == EntrySpec::Instancing::random)
        copies = spec.random_count;
      if (spec.instancing == EntrySpec::Instancing::single && (key.empty() || !uses[key].copies)) {
        // Made by one rank; its vertices and tets count once every rank knows them (settle).
        budget.check(r, n, where, 1, 0, 0);
        budget.add(1, 0, 0);
        MadeOnce d;
        d.spec = spec;
        d.node = static_cast<const YAML::Node&>(n);
        d.where = where;
        d.make = make;
        d.object = scene.objects.size();
        d.mine = !shared || static_cast<int>(d.object % static_cast<std::size_t>(limits.parts)) == limits.part;
        if (d.mine) {
          try {
            if (!key.empty() && uses[key].entries > 1) {
              // Several single-copy entries: read once here for all this rank makes.
              auto it = mesh_cache.find(key);
              if (it == mesh_cache.end()) {
                MeshReport rep;
                TetMesh m = make(&rep);
                it = mesh_cache.emplace(key, std::make_pair(std::move(m), rep)).first;
              }
              d.spec.mesh = it->second.first;
              if (spec.index == uses[key].first)
                warnings[static_cast<std::size_t>(spec.index)] = it->second.second.warnings;
            } else {
              MeshReport rep;
              d.spec.mesh = make(&rep);
              warnings[static_cast<std::size_t>(spec.index)] = rep.warnings;
            }
            place(d.spec, n, scene.objects);
          } catch (const InputError&) {
            d.error = std::current_exception();  // reported by settle, at the first such entry
          }
          d.spec.mesh = TetMesh();
        }
        scene.objects.resize(d.object + 1);  // the slot of one made elsewhere (or not made)
        made.push_back(std::move(d));
        continue;
      }
      if (!key.empty()) {
        // Read here, or received (the file's warnings belong to the first entry naming it:
        // every entry naming this file comes this way).
        auto it = mesh_cache.find(key);
        if (it == mesh_cache.end()) {
          MeshReport rep;
          TetMesh m = read_mesh(key, &rep);
          if (const auto u = unread.find(key); u != unread.end())
            r.fail(n["mesh"], "mesh file '" + key + "' of " + where + " could not be read by rank " +
                                  std::to_string(u->second) + ", but was here (did it change while the scene was read?)");
          it = mesh_cache.emplace(key, std::make_pair(std::move(m), rep)).first;
        }
        if (spec.index == uses[key].first) warnings[static_cast<std::size_t>(spec.index)] = it->second.second.warnings;
        spec.mesh = it->second.first;
      } else {
        spec.mesh = make(nullptr);
      }
      const double nv = static_cast<double>(spec.mesh.num_vertices()), nt = static_cast<double>(spec.mesh.num_tets());
      budget.check(r, n, where, copies, nv, nt);
      budget.add(copies, nv, nt);
      place(spec, n, scene.objects);
    } catch (const InputError&) {
      settle(true);  // every rank reaches it: errors of the YAML are found alike
      throw;
    }
  }
  settle(false);
  for (const auto& w : warnings) scene.warnings.insert(scene.warnings.end(), w.begin(), w.end());
  // The random copies, once every entry is read: the ranks share the placement of
  // independent regions (SceneLimits::gather). A region too full to place its copies is
  // reported at its entry, the first in scene order, as if placed one by one.
  if (const auto failed = place_random(pending, scene.objects, limits.hold_copy_meshes, limits))
    r.fail(pending_nodes[failed->entry], failed->detail);
  // Every rank keeps every object's record for the run: not the up to twice as many
  // slots the vector's growth left (352 bytes each).
  scene.objects.shrink_to_fit();
  return parsed;
}

/// Highest tet frequency of one object (tet_max_frequency); NaN when any tet's is NaN, so
/// that the caller can reject it (std::max alone would drop a NaN).
double max_tet_frequency(const TetMesh& m, const Material& mat) {
  return max_frequency(static_cast<std::ptrdiff_t>(m.num_tets()), mat,
                       [&m](std::ptrdiff_t t, double X[12]) { tet_corners(m, t, X); });
}

/// The highest tet frequency of every movable object (0 for kinematic ones), computed once
/// per distinct mesh: the copies of a multi-copy entry are rigid motions of their entry's
/// mesh (Placement::base) with one material, so they all take the frequency of that mesh
/// as the entry placed it (their placed meshes would give the same eigenvalues but for
/// the rounding of the placement); any other object its own mesh's. The meshes are shared
/// over the parts (the k-th distinct mesh on part k % parts; SceneLimits::sum adds the
/// parts' vectors), each value computed exactly as on one part; a mesh of at least
/// `spread_tets` tets (every rank holds it) is cut into `parts` consecutive ranges of tets
/// instead, each part the maximum of its range in a slot of its own after the objects'
/// values, so that one rank does not compute it alone (the maximum of the slots is the
/// one part's value). The objects in `known` take their value from it (the single-copy
/// entries, measured by the rank that made them: parse_objects).
std::vector<double> object_frequencies(const Scene& scene, int part, int parts,
                                       const std::function<void(std::vector<double>&)>& sum,
                                       const std::map<std::size_t, double>& known = {},
                                       std::int64_t spread_tets = std::numeric_limits<std::int64_t>::max()) {
  const std::size_t n = scene.objects.size();
  std::vector<double> frequency(n, 0.0);
  std::vector<std::size_t> from(n);  // the object whose value object i takes
  std::vector<std::size_t> units;    // the objects whose mesh is computed, in object order
  std::map<std::pair<const EntryMesh*, int>, std::size_t> first;  // (entry mesh, material) -> its first copy
  for (std::size_t i = 0; i < n; ++i) {
    const SceneObject& o = scene.objects[i];
    if (o.kinematic()) continue;
    from[i] = i;
    if (known.count(i)) continue;
    if (o.placement.is_copy()) {
      const auto [it, fresh] = first.emplace(std::make_pair(o.placement.base.get(), o.material), i);
      from[i] = it->second;
      if (!fresh) continue;
    }
    units.push_back(i);
  }
  const bool shared = parts > 1 && sum;
  const auto P = static_cast<std::size_t>(parts);
  std::vector<std::size_t> wide;  // units whose tets the parts share
  std::size_t whole = 0;          // units computed whole so far: the k-th on part k % parts
  for (std::size_t i : units) {
    const SceneObject& o = scene.objects[i];
    const Material& mat = scene.materials[o.material];
    // f(the unit's mesh): an entry's mesh for copies, else the object's (a view, which may
    // hold a mesh made again: kept alive while f runs)
    const auto with_mesh = [&](const auto& f) {
      if (o.placement.is_copy()) return f(o.placement.base->get());
      const auto view = scene.view_mesh(i);
      return f(view.get());
    };
    const auto nt = static_cast<std::int64_t>(o.placement.is_copy() ? o.placement.base->get().num_tets() : scene.shape(i).tets);
    if (shared && nt >= spread_tets) {
      // tets [nt part / parts, nt (part + 1) / parts), in slot `part` after the objects'
      const std::ptrdiff_t lo = nt * part / parts, hi = nt * (part + 1) / parts;
      std::vector<double> slots(P, 0.0);
      slots[static_cast<std::size_t>(part)] = with_mesh([&](const TetMesh& m) {
        return max_frequency(hi - lo, mat, [&m, lo](std::ptrdiff_t t, double X[12]) { tet_corners(m, lo + t, X); });
      });
      frequency.insert(frequency.end(), slots.begin(), slots.end());
      wide.push_back(i);
      continue;
    }
    if (!shared || static_cast<int>(whole++ % P) == part)
      frequency[i] = with_mesh([&mat](const TetMesh& m) { return max_tet_frequency(m, mat); });
  }
  if (shared) sum(frequency);  // 0 + w is w, NaN stays NaN: each value as computed alone
  for (std::size_t j = 0; j < wide.size(); ++j) {
    double w = 0;
    for (std::size_t k = 0; k < P; ++k) w = max_or_nan(w, frequency[n + j * P + k]);
    frequency[wide[j]] = w;
  }
  frequency.resize(n);
  for (const auto& [i, w] : known) frequency[i] = w;
  for (std::size_t i = 0; i < n; ++i)
    if (!scene.objects[i].kinematic()) frequency[i] = frequency[from[i]];
  return frequency;
}

/// Folds object i, with highest tet frequency w_element, into the scene's limit by
/// `bound`: its damped bound (damped_stable_step with its material's Rayleigh damping) at
/// its omega if smaller. The bound falls with omega, so an upper bound on the object's
/// omega_max is safe for every mode (stability.cpp). The mesh bound is computed once per
/// scene entry and material (`mesh_cache`: entry -> omega); the copies of an entry differ
/// by rigid motions, which change no eigenvalue, and each keeps its own element bound as
/// the ceiling.
void take_smaller(StableStep& stable, const Scene& scene, std::size_t i, double w_element, DtBound bound,
                  std::map<int, MeshFrequency>& mesh_cache) {
  const SceneObject& o = scene.objects[i];
  const Material& mat = scene.materials[o.material];
  double w = w_element, estimate = 0;
  if (bound == DtBound::mesh) {
    auto it = o.entry >= 0 ? mesh_cache.find(o.entry) : mesh_cache.end();
    if (it == mesh_cache.end()) it = mesh_cache.insert_or_assign(o.entry, mesh_max_frequency(scene.view_mesh(i).get(), mat, w_element)).first;
    w = std::min(w_element, it->second.omega);
    estimate = it->second.estimate;
  }
  const double dt = damped_stable_step(w, mat.damping_mass, mat.damping_stiffness);
  // Ties keep the first object: the result does not depend on anything but the scene.
  if (stable.object < 0 || dt < stable.dt)
    stable = {dt, static_cast<int>(i), w, mat.damping_mass, mat.damping_stiffness, bound, w_element, estimate};
}

}  // namespace

Scene load_scene_from_string(const std::string& yaml, const std::string& path, const SceneLimits& limits) {
  Reader r(path);
  YAML::Node root;
  try {
    root = YAML::Load(yaml);
  } catch (const YAML::ParserException& e) {
    throw InputError(path, e.mark.is_null() ? 0 : e.mark.line + 1, "malformed YAML: " + e.msg);
  }
  if (!root.IsMap()) throw InputError(path, 0, "a scene must be a YAML mapping with keys simulation, materials, objects");
  r.check_keys(root, {"simulation", "materials", "friction", "objects"}, "the scene");

  Scene scene;
  scene.path = path;
  scene.text = yaml;
  parse_simulation(r, r.require(root, "simulation", "the scene"), scene.sim);
  const auto mats = r.require(root, "materials", "the scene");
  if (!mats.IsSequence() || mats.size() == 0) r.fail(mats, "'materials' must be a non-empty list");
  for (const auto& m : mats) {
    Material mat = parse_material(r, m);
    for (const auto& other : scene.materials)
      if (other.name == mat.name) r.fail(m["name"], "material '" + mat.name + "' is defined twice");
    scene.materials.push_back(mat);
  }
  if (const auto f = root["friction"]) parse_friction(r, f, scene);
  else scene.friction.assign(scene.materials.size(), std::vector<Friction>(scene.materials.size(), scene.default_friction));

  const std::filesystem::path dir = std::filesystem::path(path).parent_path();
  const ParsedObjects parsed = parse_objects(r, r.require(root, "objects", "the scene"), scene, dir, limits);

  // Implicit Euler needs a symmetric positive (semi-)definite stiffness: the laws whose
  // registry entry says so (linear, and the corotational model's warped one). The
  // non-linear models' exact tangents are indefinite under compression, and CG would break
  // down (docs/models.md).
  if (scene.sim.integrator == IntegratorKind::implicit_euler)
    for (const auto& o : scene.objects) {
      const Material& mat = scene.materials[o.material];
      if (o.kinematic() || model::material_law(mat.model).implicit) continue;
      std::vector<const char*> ok;
      for (int k = 0; k < kModelKinds; ++k)
        if (model::material_law(static_cast<ModelKind>(k)).implicit) ok.push_back(kModelNames[k]);
      std::string list;  // 'a', 'b' and 'c'
      for (std::size_t k = 0; k < ok.size(); ++k)
        list.append(k == 0 ? "'" : k + 1 == ok.size() ? " and '" : ", '").append(ok[k]).append("'");
      r.fail(root["simulation"]["integrator"],
             "integrator 'implicit_euler' supports the models " + list + " only, but object '" + o.name +
                 "' uses material '" + mat.name + "' with model '" + to_string(mat.model) +
                 "'; use integrator 'verlet' or 'symplectic_euler', or one of these models");
    }

  // Time step: from the stability limit, or checked against it. A movable object's
  // highest tet frequency must be positive and finite: an overflowing stiffness (huge
  // 'young', tiny 'density') or tets whose volume underflows (extreme 'size' ratios) give
  // inf or NaN, and then no time step is stable.
  StableStep stable;
  std::map<int, MeshFrequency> mesh_cache(parsed.mesh_bound);
  const std::vector<double> frequency =
      object_frequencies(scene, limits.part, limits.parts, limits.sum, parsed.frequency, limits.spread_tets);
  // Every object's shape, now that every mesh is in hand: the ranks share the boundaries
  // (the copies placed without their meshes have theirs already).
  if (!limits.hold_copy_meshes) scene.describe_objects(limits.part, limits.parts, limits.sum);
  for (std::size_t i = 0; i < scene.objects.size(); ++i) {
    const SceneObject& o = scene.objects[i];
    if (o.kinematic()) continue;
    const double w = frequency[i];
    if (!(w > 0 && w < std::numeric_limits<double>::infinity())) {
      std::ostringstream s;
      s << "object '" << o.name << "' (material '" << scene.materials[o.material].name << "', " << o.source()
        << ") has a highest tet frequency of " << w << " rad/s, so no time step is stable (expected a positive finite "
        << "value: check 'young' and 'density' and that its tets are not flattened to zero volume)";
      r.fail(root["objects"], s.str());
    }
    take_smaller(stable, scene, i, w, scene.sim.dt_bound, mesh_cache);
  }
  if (scene.sim.dt_auto) {
    if (!std::isfinite(stable.dt))
      r.fail(root["simulation"], "'dt: auto' needs at least one movable object; give 'dt' in seconds");
    if (!(stable.dt > 0)) {
      // Only a damping term that overflows (beta omega^2 = inf) gets here.
      const SceneObject& o = scene.objects[static_cast<std::size_t>(stable.object)];
      std::ostringstream s;
      s << "object '" << o.name << "' (material '" << scene.materials[o.material].name << "') has a highest tet "
        << "frequency of " << stable.omega << " rad/s and Rayleigh damping mass " << stable.alpha << " /s, stiffness "
        << stable.beta << " s, so no explicit time step is stable (expected a smaller 'damping.stiffness'; "
        << "docs/models.md, \"Stability limit\")";
      r.fail(root["objects"], s.str());
    }
    scene.sim.dt = scene.sim.dt_safety * stable.dt;
  } else if (scene.sim.integrator != IntegratorKind::implicit_euler && scene.sim.dt > stable.dt) {
    std::ostringstream s;
    s << path << ": warning: dt = " << scene.sim.dt << " s exceeds the stable explicit limit " << stable.dt << " s ("
      << stable.explain(scene) << "); expect an unstable run, or use 'dt: auto'";
    scene.warnings.push_back(s.str());
  }
  // Step counts are 64-bit integers downstream (total_steps, steps_between_frames).
  constexpr double kMaxSteps = static_cast<double>(std::int64_t{1} << 40);
  if (scene.sim.end_time && !(*scene.sim.end_time / scene.sim.dt <= kMaxSteps)) {
    std::ostringstream s;
    s << "'end_time' " << *scene.sim.end_time << " s with dt = " << scene.sim.dt << " s takes "
      << *scene.sim.end_time / scene.sim.dt << " steps (expected at most 2^40; give a shorter 'end_time' or a larger 'dt')";
    r.fail(root["simulation"]["end_time"], s.str());
  }
  if (scene.sim.output_interval > 0 && !(scene.sim.output_interval / scene.sim.dt <= kMaxSteps)) {
    std::ostringstream s;
    s << "'output.interval' " << scene.sim.output_interval << " s is " << scene.sim.output_interval / scene.sim.dt
      << " steps of dt = " << scene.sim.dt << " s (expected at most 2^40)";
    r.fail(root["simulation"]["output"]["interval"], s.str());
  }
  if (scene.sim.output_dir.empty())
    scene.sim.output_dir = "output/" + std::filesystem::path(path).stem().string();
  return scene;
}

Scene load_scene(const std::string& path, const SceneLimits& limits) {
  std::ifstream in(path, std::ios::binary);
  std::error_code ec;
  const bool there = std::filesystem::exists(path, ec);
  if (ec) throw InputError(path, 0, "cannot look up the scene file: " + ec.message());
  if (!there) throw InputError(path, 0, "scene file does not exist");
  if (std::filesystem::is_directory(path, ec)) throw InputError(path, 0, "is a directory, expected a scene file (.yaml)");
  if (!in) throw InputError(path, 0, "cannot open the scene file for reading");
  std::ostringstream ss;
  ss << in.rdbuf();
  return load_scene_from_string(ss.str(), path, limits);
}

StableStep stable_step(const Scene& scene) { return stable_step(scene, scene.sim.dt_bound); }

StableStep stable_step(const Scene& scene, DtBound bound) {
  StableStep stable;
  std::map<int, MeshFrequency> mesh_cache;
  const std::vector<double> frequency = object_frequencies(scene, 0, 1, nullptr);
  for (std::size_t i = 0; i < scene.objects.size(); ++i)
    if (!scene.objects[i].kinematic()) take_smaller(stable, scene, i, frequency[i], bound, mesh_cache);
  return stable;
}

double stable_time_step(const Scene& scene) { return stable_step(scene).dt; }

std::string StableStep::explain(const Scene& scene) const {
  std::ostringstream s;
  if (bound == DtBound::mesh && object >= 0) {
    const SceneObject& o = scene.objects[static_cast<std::size_t>(object)];
    s << "object '" << o.name << "': 2 / the highest frequency of its assembled mesh, at most " << omega
      << " rad/s (mesh bound, certified; Lanczos estimate " << omega_estimate << " rad/s, element bound "
      << omega_element << " rad/s)";
    if (damped())
      s << ", lowered by the Rayleigh damping of material '" << scene.materials[o.material].name << "' (mass "
        << alpha << " /s, stiffness " << beta << " s; damping ratio " << damping_ratio() << ")";
    s << "; docs/models.md";
    return s.str();
  }
  if (!damped() || object < 0) {
    s << "2 / the highest element frequency, docs/models.md";
    return s.str();
  }
  const SceneObject& o = scene.objects[static_cast<std::size_t>(object)];
  s << "object '" << o.name << "': 2 / its highest element frequency " << omega << " rad/s = " << 2 / omega
    << " s, lowered by the Rayleigh damping of material '" << scene.materials[o.material].name << "' (mass " << alpha
    << " /s, stiffness " << beta << " s; damping ratio " << damping_ratio() << "); docs/models.md";
  return s.str();
}

std::int64_t total_steps(const Simulation& sim) {
  if (sim.steps) return *sim.steps;
  // A relative slack so that end_time = k * dt does not take k + 1 steps from rounding.
  return std::max<std::int64_t>(1, static_cast<std::int64_t>(std::ceil(*sim.end_time / sim.dt * (1 - 1e-12))));
}

std::int64_t steps_between_frames(const Simulation& sim) {
  if (sim.output_every > 0) return sim.output_every;
  if (sim.output_interval > 0)
    return std::max<std::int64_t>(1, static_cast<std::int64_t>(std::llround(sim.output_interval / sim.dt)));
  return std::max<std::int64_t>(1, total_steps(sim) / 100);  // about 100 frames by default
}

}  // namespace softcontact
