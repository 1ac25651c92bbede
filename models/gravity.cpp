#include "models/gravity.hpp"

#include "framework/error.hpp"

namespace weft::models {

Gravity::Gravity(const Scene& scene, const Params& /*prm*/) : mass_(scene.lumped_masses()), g_(scene.spec.gravity) {
  if (mass_.size() != scene.mesh.num_vertices())
    throw ConfigError(fmt::format("gravity: {} lumped masses for {} vertices", mass_.size(), scene.mesh.num_vertices()));
}

double Gravity::energy(const State& s) const {
  WEFT_ASSERT(s.x.size() == 3 * mass_.size(), "state has {} coordinates, expected {}", s.x.size(), 3 * mass_.size());
  double v = 0;
  for (Eigen::Index i = 0; i < mass_.size(); ++i) v -= mass_[i] * g_.dot(s.x.segment<3>(3 * i));
  return v;
}

void Gravity::add_gradient(const State& s, Eigen::VectorXd& g) const {
  WEFT_ASSERT(g.size() == s.x.size() && g.size() == 3 * mass_.size(), "gradient has size {}, expected {}", g.size(),
              3 * mass_.size());
  for (Eigen::Index i = 0; i < mass_.size(); ++i) g.segment<3>(3 * i) -= mass_[i] * g_;
}

void Gravity::energy_terms(const State& s, EnergyTerms& terms) const { terms.emplace_back("gravity", energy(s)); }

}  // namespace weft::models
