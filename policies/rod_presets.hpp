#pragma once
/// \file rod_presets.hpp
/// The curated rod combinations, apart from the cloth ones so that a cloth combination's
/// translation unit does not compile rod code (and the reverse).
#include "contact/rods/rod_response.hpp"
#include "framework/rod_simulator.hpp"
#include "integrators/rod_backward_euler.hpp"
#include "linear/banded_lu.hpp"
#include "models/discrete_elastic_rod.hpp"

namespace weft {

/// Elastic rods (hair): discrete elastic rods, the per-rod DEL minimisation, a banded LU
/// per rod, and one of the rod contact strategies (contact/rods/rod_response.hpp).
template <class Contact>
using RodSim = RodSimulator<models::DiscreteElasticRod, integrators::RodBackwardEuler, Contact, linear::BandedLu>;
using RodsNone = RodSim<contact::rods::NoRodContact>;
using RodsImpulse = RodSim<contact::rods::RodImpulse>;
using RodsLinear = RodSim<contact::rods::RodLinearCompliance>;
using RodsAdonis = RodSim<contact::rods::Adonis>;
using RodsStaggered = RodSim<contact::rods::StaggeredProjections>;
extern template class RodSimulator<models::DiscreteElasticRod, integrators::RodBackwardEuler, contact::rods::NoRodContact, linear::BandedLu>;
extern template class RodSimulator<models::DiscreteElasticRod, integrators::RodBackwardEuler, contact::rods::RodImpulse, linear::BandedLu>;
extern template class RodSimulator<models::DiscreteElasticRod, integrators::RodBackwardEuler, contact::rods::RodLinearCompliance, linear::BandedLu>;
extern template class RodSimulator<models::DiscreteElasticRod, integrators::RodBackwardEuler, contact::rods::Adonis, linear::BandedLu>;
extern template class RodSimulator<models::DiscreteElasticRod, integrators::RodBackwardEuler, contact::rods::StaggeredProjections, linear::BandedLu>;

}  // namespace weft
