// Edge-edge contacts (docs/collision.md, "Edge contacts"; docs/contact.md): two boxes
// crossed ridge on ridge with no vertex at the crossing, against the analytic overlap;
// the crossings found against a brute-force loop over every surface edge and triangle;
// and the response closing the crossing in the step.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "collide_test_util.hpp"
#include "../random_objects.hpp"
#include "softcontact/contact.hpp"

using namespace softcontact;
using namespace softcontact::test;

namespace {

// Lower box 0.15 x 0.08 x 0.08 (5 x 3 x 3 cells) turned 45 degrees about x: its top ridge
// runs along x at z = 0.04 sqrt(2). Upper box the same, laid along y and turned 45
// degrees about y: its bottom ridge runs along y, `overlap` below the lower ridge. Five
// cells along each ridge put the crossing (x = y = 0) in the middle of a ridge edge on
// both boxes, 15 mm from the nearest vertex: no vertex is inside the other box.
const double kRidge = 0.04 * std::sqrt(2.0);

std::string crossed_boxes(double overlap) {
  char z[64];
  std::snprintf(z, sizeof z, "%.17g", 2 * kRidge - overlap);
  return R"(
  - name: lower
    material: m
    primitive: {type: box, size: [0.15, 0.08, 0.08], cells: [5, 3, 3]}
    transform: {rotate: {axis: [1, 0, 0], angle: 45}}
    kinematic: true
  - name: upper
    material: m
    primitive: {type: box, size: [0.08, 0.15, 0.08], cells: [3, 5, 3]}
    transform: {rotate: {axis: [0, 1, 0], angle: 45}, translate: [0, 0, )" +
         std::string(z) + "]}\n";
}

double ridge_point_z(const World& w, const Collision& c) {
  // The point of the point-side edge at the record's parameter.
  const double* a = &w.x[3 * static_cast<std::size_t>(c.point)];
  const double* b = &w.x[3 * static_cast<std::size_t>(c.point2)];
  return c.point_weight * a[2] + (1 - c.point_weight) * b[2];
}

// Brute force: every surface edge of every object against every surface triangle of
// every other object, strict crossings by the segment's intersection with the plane and
// barycentric coordinates (a different test from the detector's signed volumes).
std::int64_t brute_force_crossings(const World& w) {
  using namespace softcontact::collide;  // V3 arithmetic
  std::set<std::pair<index_t, index_t>> edges;
  const std::size_t s = w.triangles.size() / 3;
  for (std::size_t r = 0; r < s; ++r)
    for (int k = 0; k < 3; ++k) {
      const index_t p = w.triangles[3 * r + k], q = w.triangles[3 * r + (k + 1) % 3];
      edges.insert({std::min(p, q), std::max(p, q)});
    }
  std::int64_t n = 0;
  for (const auto& [p, q] : edges) {
    const collide::V3 P = collide::load(w.x.data(), p), Q = collide::load(w.x.data(), q);
    for (std::size_t r = 0; r < s; ++r) {
      const index_t* t = &w.triangles[3 * r];
      if (w.vertex_object[static_cast<std::size_t>(t[0])] == w.vertex_object[static_cast<std::size_t>(p)]) continue;
      const collide::V3 A = collide::load(w.x.data(), t[0]), B = collide::load(w.x.data(), t[1]),
                        C = collide::load(w.x.data(), t[2]);
      const collide::V3 nrm = collide::cross(B - A, C - A);
      const double dp = collide::dot(nrm, P - A), dq = collide::dot(nrm, Q - A);
      if (!(dp * dq < 0)) continue;
      const collide::V3 X = P + (dp / (dp - dq)) * (Q - P);
      // Barycentric coordinates of X in ABC.
      const collide::V3 v0 = B - A, v1 = C - A, v2 = X - A;
      const double d00 = collide::dot(v0, v0), d01 = collide::dot(v0, v1), d11 = collide::dot(v1, v1),
                   d20 = collide::dot(v2, v0), d21 = collide::dot(v2, v1);
      const double den = d00 * d11 - d01 * d01;
      const double v = (d11 * d20 - d01 * d21) / den, u = (d00 * d21 - d01 * d20) / den;
      if (v > 0 && u > 0 && v + u < 1) ++n;
    }
  }
  return n;
}

CollisionSettings with_edges() {
  CollisionSettings s;
  s.edge_contacts = true;
  return s;
}

}  // namespace

// The two ridges cross 4 mm deep: no vertex inside, two crossings from each side, one
// edge-edge record from each side with depth exactly the overlap along z, at the middle
// of both ridge edges (weights 1/2).
TEST(EdgeContacts, CrossedRidgesGiveTheOverlapAsDepth) {
  const double overlap = 0.004;
  const World w = world_from_objects(crossed_boxes(overlap));
  CollisionDetector det(w, with_edges());
  std::vector<Collision> c;
  CollisionStats st;
  det.detect(w, nullptr, c, st);
  EXPECT_EQ(st.colliding_points, 0);
  EXPECT_EQ(st.edge_crossings, 4);
  EXPECT_EQ(st.edge_contacts, 2);
  EXPECT_EQ(st.edge_unpaired, 0);
  ASSERT_EQ(c.size(), 2u);
  for (const Collision& r : c) {
    ASSERT_GE(r.point2, 0);
    EXPECT_NEAR(r.point_weight, 0.5, 1e-9);
    EXPECT_NEAR(r.weight[0], 0.5, 1e-9);
    EXPECT_NEAR(r.weight[1], 0.5, 1e-9);
    EXPECT_EQ(r.weight[2], 0);
    const double sign = r.object == 1 ? 1 : -1;  // the upper ridge moves up, the lower one down
    EXPECT_NEAR(r.depth[0], 0, 1e-12);
    EXPECT_NEAR(r.depth[1], 0, 1e-12);
    EXPECT_NEAR(r.depth[2], sign * overlap, 1e-12);
    EXPECT_NEAR(ridge_point_z(w, r), r.object == 1 ? kRidge - overlap : kRidge, 1e-12);
    EXPECT_EQ(r.point_gid, w.vertex_gid[static_cast<std::size_t>(r.point)]);
    EXPECT_GE(r.triangle_gid, w.global_triangles);  // never a real triangle's id
  }
  EXPECT_NE(c[0].object, c[1].object);
}

// Off (the default): the crossing is not seen at all.
TEST(EdgeContacts, SwitchedOffNothingIsFound) {
  const World w = world_from_objects(crossed_boxes(0.004));
  CollisionDetector det(w, {});
  std::vector<Collision> c;
  CollisionStats st;
  det.detect(w, nullptr, c, st);
  EXPECT_TRUE(c.empty());
  EXPECT_EQ(st.edge_crossings, 0);
}

// Every strict crossing between bodies is found: the count equals the brute force's on
// random overlapping scenes (boxes and balls, some deeply interpenetrating).
TEST(EdgeContacts, CrossingsMatchBruteForceOnRandomScenes) {
  std::int64_t total = 0;
  for (std::uint64_t seed = 1; seed <= 6; ++seed) {
    const World w = random_scene(seed, 6, seed % 2 ? 0.0 : 0.01);
    CollisionDetector det(w, with_edges());
    std::vector<Collision> c;
    CollisionStats st;
    det.detect(w, nullptr, c, st);
    EXPECT_EQ(st.edge_crossings, brute_force_crossings(w)) << "seed " << seed;
    total += st.edge_crossings;
    for (const Collision& r : c) {
      if (r.point2 < 0) continue;
      EXPECT_GT(r.point_weight, -1e-15);
      EXPECT_LT(r.point_weight, 1 + 1e-15);
      EXPECT_NEAR(r.weight[0] + r.weight[1] + r.weight[2], 1, 1e-12);
      EXPECT_TRUE(std::isfinite(r.depth[0]) && std::isfinite(r.depth[1]) && std::isfinite(r.depth[2]));
    }
  }
  EXPECT_GT(total, 100);
}

// The candidate pairs kept across steps (the Verlet skin, item 2) find the same crossings
// as pairs found again every step: objects of random overlapping scenes drift through
// each other at 0.02 median edges a step (each vertex also jittered by up to 0.005)
// for 60 steps; every step the crossings are counted by brute force and the records of
// the two detectors compared exactly. With a skin of 0.25 cells the pairs are found
// again about every 0.125 / 0.025 = 5 steps, not every step.
TEST(EdgeContacts, PairsKeptAcrossStepsFindEveryCrossing) {
  std::int64_t total = 0, searches = 0, steps = 0;
  for (std::uint64_t seed = 11; seed <= 13; ++seed) {
    World w = random_scene(seed, 6, 0.0);
    const double h = collide::build_collision_topology(w).mean_edge_length;
    CollisionSettings fresh = with_edges();
    fresh.edge_skin = 0;
    CollisionDetector kept(w, with_edges()), found(w, fresh);
    Drift drift(seed, 6, 0.02 * h, 0.005 * h);
    for (int step = 0; step < 60; ++step) {
      drift.step(w);
      std::vector<Collision> a, b;
      CollisionStats sa, sb;
      kept.detect(w, nullptr, a, sa);
      found.detect(w, nullptr, b, sb);
      ASSERT_EQ(sa.edge_crossings, brute_force_crossings(w)) << "seed " << seed << " step " << step;
      ASSERT_EQ(sb.edge_crossings, sa.edge_crossings);
      ASSERT_EQ(a.size(), b.size());
      for (std::size_t q = 0; q < a.size(); ++q) {
        EXPECT_EQ(a[q].point, b[q].point);
        EXPECT_EQ(a[q].point2, b[q].point2);
        EXPECT_EQ(a[q].triangle_gid, b[q].triangle_gid);
        for (int d = 0; d < 3; ++d) EXPECT_EQ(a[q].depth[d], b[q].depth[d]);
        EXPECT_EQ(a[q].point_weight, b[q].point_weight);
      }
      EXPECT_EQ(sb.edge_pair_searches, 1);
      total += sa.edge_crossings;
      searches += sa.edge_pair_searches;
      ++steps;
    }
  }
  EXPECT_GT(total, 500);
  EXPECT_GE(searches, steps / 10);  // found again as the objects move
  EXPECT_LE(searches, steps / 3);   // but not every step
}

// The response closes the crossing in the step: the upper ridge (movable, the lower box
// kinematic) ends exactly on the lower ridge, although the two mirror records push the
// same four vertices (the shares split them, so the motion is applied once).
TEST(EdgeContacts, ResponseClosesTheCrossingOnce) {
  const double overlap = 0.004;
  const Scene scene = load_scene_from_string(std::string(kMaterials) + "objects:\n" + crossed_boxes(overlap), "t.yaml");
  World w = build_world(scene, block_partition(scene, 1), 0);
  w.x_prev = w.x;  // no motion within the step: all of it is an old overlap
  Scene s2 = scene;
  s2.sim.separation_speed = 1e3;
  CollisionDetector det(w, with_edges());
  std::vector<Collision> c;
  CollisionStats st;
  det.detect(w, nullptr, c, st);
  ASSERT_EQ(c.size(), 2u);
  const Collision upper = c[0].object == 1 ? c[0] : c[1];
  ContactResponse solver(s2, w);
  ContactStats cs;
  solver.respond(w, c, 1e-3, cs, nullptr);
  EXPECT_NEAR(ridge_point_z(w, upper), kRidge, 1e-12);
  // Both ridge vertices rose by the overlap (the crossing is in the middle of the edge).
  EXPECT_NEAR(w.x[3 * static_cast<std::size_t>(upper.point) + 2], kRidge - overlap + overlap, 1e-12);
  EXPECT_NEAR(w.x[3 * static_cast<std::size_t>(upper.point2) + 2], kRidge, 1e-12);
  // And nothing crosses any more.
  CollisionStats after;
  det.detect(w, nullptr, c, after);
  EXPECT_EQ(after.edge_contacts, 0);
  EXPECT_EQ(after.colliding_points, 0);
}

namespace {

// The two crossed boxes as one object (one mesh file, two components): the same
// interlock, now a body against itself.
World crossed_boxes_as_one(double overlap, bool self, const std::string& path) {
  const Scene two = load_scene_from_string(std::string(kMaterials) + "objects:\n" + crossed_boxes(overlap), "t.yaml");
  std::FILE* f = std::fopen(path.c_str(), "w");
  EXPECT_NE(f, nullptr);
  std::size_t nv = 0, nt = 0;
  for (const SceneObject& o : two.objects) {
    nv += o.mesh.num_vertices();
    nt += o.mesh.num_tets();
  }
  std::fprintf(f, "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n%zu\n", nv);
  std::size_t id = 0;
  for (const SceneObject& o : two.objects)
    for (std::size_t v = 0; v < o.mesh.num_vertices(); ++v, ++id)
      std::fprintf(f, "%zu %.17g %.17g %.17g\n", id + 1, o.mesh.points[3 * v], o.mesh.points[3 * v + 1], o.mesh.points[3 * v + 2]);
  std::fprintf(f, "$EndNodes\n$Elements\n%zu\n", nt);
  std::size_t base = 0, e = 0;
  for (const SceneObject& o : two.objects) {
    for (std::size_t t = 0; t < o.mesh.num_tets(); ++t, ++e) {
      const index_t* c = &o.mesh.tets[4 * t];
      std::fprintf(f, "%zu 4 2 1 1 %zu %zu %zu %zu\n", e + 1, base + c[0] + 1, base + c[1] + 1, base + c[2] + 1, base + c[3] + 1);
    }
    base += o.mesh.num_vertices();
  }
  std::fprintf(f, "$EndElements\n");
  std::fclose(f);
  std::string yaml = std::string(kMaterials);
  yaml.replace(yaml.find("steps: 1}"), 9, std::string("steps: 1, self_collisions: ") + (self ? "true" : "false") + "}");
  const Scene one = load_scene_from_string(yaml + "objects:\n  - {name: both, material: m, mesh: " + path + "}\n", "t.yaml");
  return build_world(one, block_partition(one, 1), 0);
}

}  // namespace

// Self-contact: the crossed ridges of one body's two parts give the same two edge-edge
// records as two bodies (depth the overlap along z, weights 1/2), now with object ==
// other_object; without self-contact nothing is found (one body, no partner).
TEST(EdgeContacts, SelfCrossingOfOneBodyGivesTheSameRecords) {
  const double overlap = 0.004;
  const std::string path = testing::TempDir() + "crossed_as_one.msh";
  for (bool self : {false, true}) {
    const World w = crossed_boxes_as_one(overlap, self, path);
    CollisionSettings set = with_edges();
    set.self_collisions = self;
    CollisionDetector det(w, set);
    std::vector<Collision> c;
    CollisionStats st;
    det.detect(w, nullptr, c, st);
    EXPECT_EQ(st.colliding_points, 0);
    if (!self) {
      EXPECT_TRUE(c.empty());
      EXPECT_EQ(st.edge_crossings, 0);
      continue;
    }
    EXPECT_EQ(st.edge_crossings, 4);
    EXPECT_EQ(st.edge_unpaired, 0);
    ASSERT_EQ(c.size(), 2u);
    double sum_z = 0;
    for (const Collision& r : c) {
      EXPECT_EQ(r.object, 0);
      EXPECT_EQ(r.other_object, 0);
      EXPECT_NEAR(r.point_weight, 0.5, 1e-9);
      EXPECT_NEAR(r.weight[0], 0.5, 1e-9);
      EXPECT_NEAR(r.weight[1], 0.5, 1e-9);
      EXPECT_NEAR(r.depth[0], 0, 1e-12);
      EXPECT_NEAR(r.depth[1], 0, 1e-12);
      EXPECT_NEAR(std::abs(r.depth[2]), overlap, 1e-12);
      sum_z += r.depth[2];
    }
    EXPECT_NEAR(sum_z, 0, 1e-12);  // one ridge pushed up, the other down
  }
  std::remove(path.c_str());
}

namespace {

// Item 7 of edge_contacts.hpp, exactly: B is a square pyramid standing on its apex V at
// the origin (two tets; base 0.1 x 0.1 at z = 0.1, so its four side faces are the planes
// |x| = z / 2 and |y| = z / 2, meeting only at V), kinematic. A is one tet whose edge
// e1 = (p0, p1) runs along y at x = eps, z = h, from y = -0.05 to 0.05, its other two
// corners 1 mm higher and far off (x = eps -+ 0.2, y = 0.2): e1 passes through B's faces y = -z/2 and y = z/2 (which
// share only V) above V, and no vertex of either lies inside the other. The chord of e1
// inside B lies behind the plane x = z/2 by (h/2 - eps) / sqrt(5/4) everywhere, the
// smallest of the moves of the rule (the bisector of the two crossed faces would move it
// down by h, the face x = -z/2 by (h/2 + eps) / sqrt(5/4)).
void write_msh(const std::string& path, const std::vector<std::array<double, 3>>& p,
               const std::vector<std::array<int, 4>>& tets) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  ASSERT_NE(f, nullptr);
  std::fprintf(f, "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n%zu\n", p.size());
  for (std::size_t i = 0; i < p.size(); ++i) std::fprintf(f, "%zu %.17g %.17g %.17g\n", i + 1, p[i][0], p[i][1], p[i][2]);
  std::fprintf(f, "$EndNodes\n$Elements\n%zu\n", tets.size());
  for (std::size_t i = 0; i < tets.size(); ++i)
    std::fprintf(f, "%zu 4 2 1 1 %d %d %d %d\n", i + 1, tets[i][0], tets[i][1], tets[i][2], tets[i][3]);
  std::fprintf(f, "$EndElements\n");
  std::fclose(f);
}

Scene apex_scene(double h, double eps) {
  const std::string dir = testing::TempDir();
  // 1-based: V, then the base corners counter-clockwise seen from above.
  write_msh(dir + "pyramid.msh", {{0, 0, 0}, {0.05, 0.05, 0.1}, {-0.05, 0.05, 0.1}, {-0.05, -0.05, 0.1}, {0.05, -0.05, 0.1}},
            {{{1, 2, 3, 4}}, {{1, 2, 4, 5}}});
  write_msh(dir + "wedge.msh", {{eps, -0.05, h}, {eps, 0.05, h}, {eps - 0.2, 0.2, h + 0.001}, {eps + 0.2, 0.2, h + 0.001}},
            {{{1, 2, 3, 4}}});
  return load_scene_from_string(std::string(kMaterials) + "objects:\n  - {name: pyramid, material: m, mesh: " + dir +
                                    "pyramid.msh, kinematic: true}\n  - {name: wedge, material: m, mesh: " + dir +
                                    "wedge.msh}\n",
                                "t.yaml");
}

}  // namespace

// The record of item 7: the point side e1 with weights 1/2 (V's nearest point on e1 is
// its middle), the other side V alone, depth (h/2 - eps) / sqrt(5/4) along the outward
// normal (1, 0, -1/2) / sqrt(5/4) of the face x = z/2. (The pyramid's four edges from V
// also pass through the thin wedge: item 4 records of their own.) Then the response to
// this record alone (B kinematic, all of it an old overlap at an unlimited separation
// speed) moves e1 onto that face: e1 no longer passes through the pyramid.
TEST(EdgeContacts, EdgeUnderAVertexMovesOutThroughTheNearestFace) {
  const double h = 0.01, eps = 0.001;
  const Scene scene = apex_scene(h, eps);
  World w = build_world(scene, block_partition(scene, 1), 0);
  w.x_prev = w.x;
  CollisionDetector det(w, with_edges());
  std::vector<Collision> c;
  CollisionStats st;
  det.detect(w, nullptr, c, st);
  EXPECT_EQ(st.colliding_points, 0);
  EXPECT_EQ(st.edge_unpaired, 0);
  const index_t apex = 0;  // the pyramid's first vertex
  std::vector<Collision> under;
  for (const Collision& q : c)
    if (q.object == 1 && q.triangle[0] == apex && q.triangle[1] == apex) under.push_back(q);
  ASSERT_EQ(under.size(), 1u);
  const Collision& r = under[0];
  EXPECT_EQ(r.other_object, 0);
  ASSERT_GE(r.point2, 0);
  EXPECT_EQ(r.weight[0], 1);
  EXPECT_NEAR(r.point_weight, 0.5, 1e-12);
  const double k = std::sqrt(1.25), d = (h / 2 - eps) / k;
  EXPECT_NEAR(r.depth[0], d / k, 1e-12);
  EXPECT_NEAR(r.depth[1], 0, 1e-12);
  EXPECT_NEAR(r.depth[2], -0.5 * d / k, 1e-12);

  Scene s2 = scene;
  s2.sim.separation_speed = 1e3;
  ContactResponse solver(s2, w);
  ContactStats cs;
  solver.respond(w, under, 1e-3, cs, nullptr);
  for (index_t v : {r.point, r.point2}) {  // on the plane x = z / 2
    const double* p = &w.x[3 * static_cast<std::size_t>(v)];
    EXPECT_NEAR(p[0], p[2] / 2, 1e-12);
  }
  det.detect(w, nullptr, c, st);
  for (const Collision& q : c) EXPECT_FALSE(q.object == 1 && q.triangle[0] == apex && q.triangle[1] == apex);
}
