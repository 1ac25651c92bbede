#pragma once
/// \file gravity.hpp
/// Uniform gravity as a potential: V(x) = -sum_i m_i g . x_i with the scene's lumped masses.
#include <Eigen/Core>

#include <string_view>

#include "framework/block_csr.hpp"
#include "framework/concepts.hpp"
#include "framework/scene.hpp"
#include "framework/state.hpp"

namespace weft::models {

/// Gravity potential V = -sum_i m_i g . x_i, g = `SceneSpec::gravity`, m = `Scene::lumped_masses()`.
/// Linear in x: gradient -m_i g, zero Hessian (registers no stencil).
class Gravity {
 public:
  /// No options: the acceleration is the scene's `gravity`.
  struct Params {
    template <class V>
    void visit(V&) {}
  };
  static constexpr std::string_view name = "gravity";
  static constexpr bool stateless = true;  ///< checkpoints: nothing kept between steps

  Gravity(const Scene& scene, const Params& prm);

  void declare(AssemblyPlan&) {}
  /// V = -sum_i m_i g . x_i [J].
  double energy(const State& s) const;
  /// g_i += -m_i g.
  void add_gradient(const State& s, Eigen::VectorXd& g) const;
  void add_hessian(const State&, ElementBuffer&, HessianMode) const {}
  /// Appends ("gravity", V).
  void energy_terms(const State& s, EnergyTerms& terms) const;
  /// False if a position is not finite.
  bool admissible(const State& s) const { return s.x.allFinite(); }

  const Eigen::VectorXd& masses() const { return mass_; }
  const Eigen::Vector3d& acceleration() const { return g_; }

 private:
  Eigen::VectorXd mass_;  // #V [kg]
  Eigen::Vector3d g_;     // [m/s^2]
};

static_assert(EnergyModel<Gravity>);

}  // namespace weft::models
