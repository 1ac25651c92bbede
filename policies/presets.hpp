#pragma once
/// \file presets.hpp
/// Named energies and the curated combinations of policies. Each combination is
/// instantiated once, in its own translation unit under policies/combos/, and declared
/// `extern template` here so no other file instantiates it again.
#include "contact/barrier.hpp"
#include "contact/impulse.hpp"
#include "contact/linear_compliance.hpp"
#include "contact/no_contact.hpp"
#include "contact/implicit_contact.hpp"
#include "contact/obstacle_penalty.hpp"
#include "framework/simulator.hpp"
#include "integrators/backward_euler_root.hpp"
#include "integrators/incremental_potential.hpp"
#include "integrators/linearly_implicit.hpp"
#include "linear/direct.hpp"
#include "linear/pcg.hpp"
#include "linear/sa_ppcg.hpp"
#include "models/energy_sum.hpp"
#include "models/gravity.hpp"
#include "models/hinge_bending.hpp"
#include "models/stvk_membrane.hpp"

namespace weft {

/// Isotropic StVK membrane + discrete-shells hinge bending (theta) + gravity.
using ClothTheta = models::EnergySum<models::StvkMembrane<models::Isotropic>, models::HingeBending<models::ThetaEnergy>,
                                     models::Gravity>;
/// Same with the tan(theta/2) bending energy of thesis Eq. 5.8.
using ClothTan = models::EnergySum<models::StvkMembrane<models::Isotropic>, models::HingeBending<models::TanEnergy>,
                                   models::Gravity>;

/// Orthotropic StVK membrane (warp/weft; also accepts isotropic cloths) + hinge bending (theta) + gravity.
using ClothOrtho = models::EnergySum<models::StvkMembrane<models::Orthotropic>, models::HingeBending<models::ThetaEnergy>,
                                     models::Gravity>;

using ClothIpDirect = Simulator<ClothTheta, integrators::IncrementalPotential, contact::NoContact, linear::Direct>;
using ClothTanIpDirect = Simulator<ClothTan, integrators::IncrementalPotential, contact::NoContact, linear::Direct>;
using ClothIpPenaltyDirect = Simulator<ClothTheta, integrators::IncrementalPotential, contact::ObstaclePenalty, linear::Direct>;
using ClothIpImpulseDirect = Simulator<ClothTheta, integrators::IncrementalPotential, contact::Impulse, linear::Direct>;
using ClothIpComplianceDirect = Simulator<ClothTheta, integrators::IncrementalPotential, contact::LinearCompliance, linear::Direct>;
using ClothIpConstraintsDirect = Simulator<ClothTheta, integrators::IncrementalPotential, contact::ImplicitContact, linear::Direct>;
using ClothLieConstraintsDiagPcg = Simulator<ClothTheta, integrators::LinearlyImplicit, contact::ImplicitContact, linear::DiagPcg>;
using ClothIpConstraintsSaPpcg = Simulator<ClothTheta, integrators::IncrementalPotential, contact::ImplicitContact, linear::SaPpcg>;
using ClothOrthoIpDirect = Simulator<ClothOrtho, integrators::IncrementalPotential, contact::NoContact, linear::Direct>;
using ClothRootDirect = Simulator<ClothTheta, integrators::BackwardEulerRoot, contact::NoContact, linear::Direct>;
using ClothLieDirect = Simulator<ClothTheta, integrators::LinearlyImplicit, contact::NoContact, linear::Direct>;
using ClothIpDiagPcg = Simulator<ClothTheta, integrators::IncrementalPotential, contact::NoContact, linear::DiagPcg>;
using ClothIpSaPpcg = Simulator<ClothTheta, integrators::IncrementalPotential, contact::NoContact, linear::SaPpcg>;
using ClothLieSaPpcg = Simulator<ClothTheta, integrators::LinearlyImplicit, contact::NoContact, linear::SaPpcg>;
using ClothIpDiagPpcg = Simulator<ClothTheta, integrators::IncrementalPotential, contact::NoContact, linear::DiagPpcg>;
using ClothIpSaMpcg = Simulator<ClothTheta, integrators::IncrementalPotential, contact::NoContact, linear::SaMpcg>;

extern template class Simulator<ClothTheta, integrators::IncrementalPotential, contact::NoContact, linear::Direct>;
extern template class Simulator<ClothTan, integrators::IncrementalPotential, contact::NoContact, linear::Direct>;
extern template class Simulator<ClothTheta, integrators::IncrementalPotential, contact::ObstaclePenalty, linear::Direct>;
extern template class Simulator<ClothTheta, integrators::IncrementalPotential, contact::Impulse, linear::Direct>;
extern template class Simulator<ClothTheta, integrators::IncrementalPotential, contact::LinearCompliance, linear::Direct>;
extern template class Simulator<ClothTheta, integrators::IncrementalPotential, contact::ImplicitContact, linear::Direct>;
extern template class Simulator<ClothTheta, integrators::LinearlyImplicit, contact::ImplicitContact, linear::DiagPcg>;
extern template class Simulator<ClothTheta, integrators::IncrementalPotential, contact::ImplicitContact, linear::SaPpcg>;
extern template class Simulator<ClothTheta, integrators::IncrementalPotential, contact::Barrier, linear::Direct>;
extern template class Simulator<ClothTheta, integrators::IncrementalPotential, contact::Barrier, linear::SaPpcg>;
extern template class Simulator<ClothOrtho, integrators::IncrementalPotential, contact::NoContact, linear::Direct>;
extern template class Simulator<ClothTheta, integrators::BackwardEulerRoot, contact::NoContact, linear::Direct>;
extern template class Simulator<ClothTheta, integrators::LinearlyImplicit, contact::NoContact, linear::Direct>;
extern template class Simulator<ClothTheta, integrators::IncrementalPotential, contact::NoContact, linear::DiagPcg>;
extern template class Simulator<ClothTheta, integrators::IncrementalPotential, contact::NoContact, linear::SaPpcg>;
extern template class Simulator<ClothTheta, integrators::LinearlyImplicit, contact::NoContact, linear::SaPpcg>;
extern template class Simulator<ClothTheta, integrators::IncrementalPotential, contact::NoContact, linear::DiagPpcg>;
extern template class Simulator<ClothTheta, integrators::IncrementalPotential, contact::NoContact, linear::SaMpcg>;

}  // namespace weft
