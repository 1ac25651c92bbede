#pragma once
// A custom energy policy: edge springs E = sum_e k/2 (|x_j - x_i| - L_e)^2, exact gradient and Hessian.
// It models weft::EnergyModel, so it composes with every other policy (docs/tour.md walks through it).
#include <cmath>
#include <vector>
#include "framework/concepts.hpp"
#include "framework/scene.hpp"

struct EdgeSprings {
  struct Params {  // the scene's "energy": {"edge_springs": {"stiffness": ...}}
    double stiffness = 100;
    template <class V> void visit(V& v) { v.field("stiffness", stiffness, {weft::Unit::none, weft::Range::gt(0), "spring constant [N/m]"}); }
  };
  static constexpr std::string_view name = "edge_springs";
  EdgeSprings(const weft::Scene& s, const Params& p) : k(p.stiffness), edges(s.mesh.edges()) {
    for (auto [i, j] : edges) rest.push_back((s.mesh.rest().row(j) - s.mesh.rest().row(i)).norm()), ids.insert(ids.end(), {i, j});
  }
  void declare(weft::AssemblyPlan& plan) { group = plan.add_group(2, ids); }  // one 2-vertex stencil per edge
  Eigen::Vector3d d(const weft::State& s, int e) const { return s.position(edges[e][1]) - s.position(edges[e][0]); }
  double energy(const weft::State& s) const {
    double E = 0;
    for (int e = 0; e < int(edges.size()); ++e) E += 0.5 * k * std::pow(d(s, e).norm() - rest[e], 2);
    return E;
  }
  void add_gradient(const weft::State& s, Eigen::VectorXd& g) const {
    for (int e = 0; e < int(edges.size()); ++e) {
      const Eigen::Vector3d f = k * (d(s, e).norm() - rest[e]) * d(s, e).normalized();  // dE/dx_j = -dE/dx_i
      g.segment<3>(3 * edges[e][1]) += f, g.segment<3>(3 * edges[e][0]) -= f;
    }
  }
  void add_hessian(const weft::State& s, weft::ElementBuffer& buf, weft::HessianMode mode) const {
    buf.for_each(group, [&](int e) {  // H = k (u u^T + (1 - L/l)(I - u u^T)); projected: 1 - L/l clamped at 0
      const Eigen::Vector3d u = d(s, e).normalized();
      const double c = 1 - rest[e] / d(s, e).norm();
      const Eigen::Matrix3d P = u * u.transpose(), H = k * (P + (mode == weft::HessianMode::exact ? c : std::max(c, 0.0)) * (Eigen::Matrix3d::Identity() - P));
      Eigen::Matrix<double, 6, 6> local;
      local << H, -H, -H, H;
      buf.set(group, e, local);
    });
  }
  void energy_terms(const weft::State& s, weft::EnergyTerms& t) const { t.emplace_back("springs", energy(s)); }
  bool admissible(const weft::State& s) const { return s.x.allFinite(); }
  double k;                                // [N/m]
  std::vector<std::array<int, 2>> edges;   // the mesh's edges, and their rest lengths [m]
  std::vector<double> rest;
  std::vector<int> ids;                    // stencils for the assembly plan
  int group = -1;
};
static_assert(weft::EnergyModel<EdgeSprings>);
