// Maxima over checks and their JSON form (verify.hpp).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "softcontact/verify.hpp"

namespace softcontact {

namespace {

void peak(VerifyPeak& p, double value, const VerifyFrame& f) {
  if (p.step < 0 || value > p.value) {
    p.value = value;
    p.step = f.step;
    p.time = f.time;
  }
}

std::string num(double x) {
  if (!std::isfinite(x)) return "null";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.9g", x);
  return buf;
}

class Json {
public:
  Json& key(const char* k) {
    s_ << (first_ ? "" : ", ") << '"' << k << "\": ";
    first_ = false;
    return *this;
  }
  Json& val(double x) {
    s_ << num(x);
    return *this;
  }
  Json& val(std::int64_t x) {
    s_ << x;
    return *this;
  }
  Json& raw(const std::string& x) {
    s_ << x;
    return *this;
  }
  std::string str() const {
    std::string out(1, '{');
    out += s_.str();
    out += '}';
    return out;
  }

private:
  std::ostringstream s_;
  bool first_ = true;
};

std::string inside_json(const InsideStats& s, double h) {
  Json j;
  j.key("count").val(s.count).key("max_depth").val(s.max_depth).key("max_depth_edges").val(s.max_depth / h);
  j.key("p99_depth").val(s.p99_depth).key("p99_depth_edges").val(s.p99_depth / h);
  j.key("vertex").val(s.vertex).key("object").val(std::int64_t{s.object}).key("in_object").val(std::int64_t{s.in_object});
  return j.str();
}

std::string crossing_json(const CrossingStats& x, double h) {
  Json c;
  c.key("count").val(x.count).key("without_inside_vertex").val(x.without_inside_vertex);
  c.key("grazing").val(x.grazing);
  c.key("max_depth").val(x.max_depth).key("max_depth_edges").val(x.max_depth / h);
  std::ostringstream edge;
  edge << '[' << x.edge[0] << ", " << x.edge[1] << ']';
  c.key("edge").raw(edge.str());
  c.key("triangle").val(x.triangle).key("object").val(std::int64_t{x.object});
  c.key("in_object").val(std::int64_t{x.in_object});
  return c.str();
}

std::string peak_json(const VerifyPeak& p) {
  Json j;
  j.key("value").val(p.value).key("step").val(p.step).key("time").val(p.time);
  return j.str();
}

}  // namespace

void VerifyMaxima::add(const VerifyFrame& f) {
  if (checks == 0 || f.surface.max_depth > deepest.surface.max_depth) deepest = f;
  ++checks;
  surface_depths.push_back(f.surface_depth());
  for (int k = 0; k < kRecordStatuses; ++k) deep_by_record[k] += f.deep_by_record[k];
  peak(surface_count, static_cast<double>(f.surface.count), f);
  peak(surface_depth, f.surface_depth(), f);
  peak(interior_count, static_cast<double>(f.interior.count), f);
  peak(interior_depth, f.interior_depth(), f);
  peak(self_count, static_cast<double>(f.self.count), f);
  peak(self_depth, f.self_depth(), f);
  peak(self_crossings, static_cast<double>(f.self_crossings.count), f);
  peak(self_crossing_depth, f.self_crossing_depth(), f);
  peak(crossings, static_cast<double>(f.crossings.count), f);
  peak(crossings_without_inside_vertex, static_cast<double>(f.crossings.without_inside_vertex), f);
  peak(crossing_depth, f.crossing_depth(), f);
  peak(inverted, static_cast<double>(f.inverted), f);
  peak(nonfinite, static_cast<double>(f.nonfinite), f);
  if (max_speed.step < 0 || f.max_speed > max_speed.value) fastest_vertex = f.fastest;
  peak(max_speed, f.max_speed, f);
  peak(speed_ratio, f.speed_ratio, f);
}

std::int64_t VerifyMaxima::checks_deeper_than(double limit) const {
  return std::count_if(surface_depths.begin(), surface_depths.end(), [&](double d) { return d > limit; });
}

double VerifyMaxima::surface_depth_quantile(double q) const {
  if (surface_depths.empty()) return 0;
  std::vector<double> s = surface_depths;
  const auto n = s.size();
  const auto k = std::min(n - 1, static_cast<std::size_t>(std::ceil(q * static_cast<double>(n))) - (q > 0 ? 1 : 0));
  std::nth_element(s.begin(), s.begin() + static_cast<std::ptrdiff_t>(k), s.end());
  return s[k];
}

std::string to_json(const VerifyFrame& f) {
  const double h = f.median_edge;
  Json j;
  j.key("step").val(f.step).key("time").val(f.time).key("median_edge").val(h);
  j.key("surface").raw(inside_json(f.surface, h)).key("interior").raw(inside_json(f.interior, h));
  j.key("self").raw(inside_json(f.self, h));
  j.key("self_crossings").raw(crossing_json(f.self_crossings, h));
  j.key("crossings").raw(crossing_json(f.crossings, h));
  j.key("inverted").val(f.inverted).key("first_inverted").val(f.first_inverted).key("nonfinite").val(f.nonfinite);
  j.key("max_speed").val(f.max_speed).key("fastest_vertex").val(f.fastest).key("speed_ratio").val(f.speed_ratio);
  return j.str();
}

std::string to_json(const VerifyMaxima& m) {
  Json j;
  j.key("checks").val(m.checks);
  j.key("surface_count").raw(peak_json(m.surface_count)).key("surface_depth_edges").raw(peak_json(m.surface_depth));
  j.key("interior_count").raw(peak_json(m.interior_count)).key("interior_depth_edges").raw(peak_json(m.interior_depth));
  j.key("self_count").raw(peak_json(m.self_count)).key("self_depth_edges").raw(peak_json(m.self_depth));
  j.key("self_crossings").raw(peak_json(m.self_crossings));
  j.key("self_crossing_depth_edges").raw(peak_json(m.self_crossing_depth));
  j.key("crossings").raw(peak_json(m.crossings));
  j.key("crossings_without_inside_vertex").raw(peak_json(m.crossings_without_inside_vertex));
  j.key("crossing_depth_edges").raw(peak_json(m.crossing_depth));
  j.key("inverted").raw(peak_json(m.inverted)).key("nonfinite").raw(peak_json(m.nonfinite));
  j.key("max_speed").raw(peak_json(m.max_speed)).key("speed_ratio").raw(peak_json(m.speed_ratio));
  j.key("fastest_vertex").val(std::int64_t{m.fastest_vertex});
  {
    Json d;
    d.key("median").val(m.surface_depth_quantile(0.5)).key("p90").val(m.surface_depth_quantile(0.9));
    d.key("over_0.005").val(m.checks_deeper_than(0.005)).key("over_0.01").val(m.checks_deeper_than(0.01));
    d.key("over_0.02").val(m.checks_deeper_than(0.02));
    j.key("surface_depth_per_check").raw(d.str());
  }
  {
    Json r;
    r.key("no_record").val(m.deep_by_record[kNoRecord]).key("capped").val(m.deep_by_record[kCapped]);
    r.key("under_closed").val(m.deep_by_record[kUnderClosed]).key("closed").val(m.deep_by_record[kClosed]);
    j.key("deep_vertices_by_record").raw(r.str());
  }
  j.key("deepest").raw(m.checks > 0 ? to_json(m.deepest) : "null");
  return j.str();
}

}  // namespace softcontact
