#pragma once
/// \file no_contact.hpp
/// `NoContact`: the strategy for scenes without contact. Every member is an empty inline
/// function, so a simulator composed with it compiles no contact code at all.
#include <string_view>

#include "framework/concepts.hpp"

namespace weft::contact {

class NoContact {
 public:
  static constexpr std::string_view name = "none";
  static constexpr bool stateless = true;  ///< checkpoints: nothing kept
  static constexpr bool provides_potential = true;  // a zero potential
  static constexpr bool inert = true;               // the simulator skips the contact stage
  struct Params {
    template <class V>
    void visit(V&) {}
  };
  NoContact(const Scene&, const Params&) {}
  void declare(AssemblyPlan&) {}
  ContactReport begin_step(const State&, double) { return {}; }
  double energy(const State&) const { return 0.0; }
  void add_gradient(const State&, Eigen::VectorXd&) const {}
  void add_hessian(const State&, ElementBuffer&, HessianMode) const {}
  ContactReport end_step(State&, double) { return {}; }
};

static_assert(ContactStrategy<NoContact>);

}  // namespace weft::contact
