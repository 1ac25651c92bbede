#pragma once
/// \file energy_sum.hpp
/// A sum of energy models that is itself an `EnergyModel` (like AMGCL's `make_solver` is a
/// preconditioner): `EnergySum<StvkMembrane<Isotropic>, HingeBending<ThetaEnergy>, Gravity>`.
#include <Eigen/Core>

#include <cstddef>
#include <string_view>
#include <tuple>
#include <utility>

#include "framework/block_csr.hpp"
#include "framework/checkpoint.hpp"
#include "framework/concepts.hpp"
#include "framework/params.hpp"
#include "framework/scene.hpp"
#include "framework/state.hpp"
#include "models/gravity.hpp"
#include "models/hinge_bending.hpp"
#include "models/stvk_membrane.hpp"

namespace weft::models {

/// V = sum of the terms' energies; every member forwards to each term in order.
template <EnergyModel... Terms>
class EnergySum {
 public:
  /// The terms' parameters, one section per term named by its `name`:
  ///   {"stvk_membrane": {...}, "hinge_bending": {...}, "gravity": {...}}.
  struct Params {
    std::tuple<typename Terms::Params...> terms;  ///< in the order of `Terms`
    template <class V>
    void visit(V& v) {
      // Term names are string literals, so `data()` is null-terminated.
      std::apply([&](auto&... p) { (v.section(Terms::name.data(), p), ...); }, terms);
    }
  };
  static constexpr std::string_view name = "energy_sum";
  /// Checkpoints (framework/checkpoint.hpp): stateless when every term is (a term that
  /// saves state would need its arrays forwarded here; none does).
  static constexpr bool stateless = (StatelessPolicy<Terms> && ...);

  /// Every violation of every term's `validate` (terms without one are skipped).
  static Checker validate(const Params& prm) {
    Checker c;
    std::apply([&](const auto&... p) { (validate_term<Terms>(p, c), ...); }, prm.terms);
    return c;
  }

  /// Builds each term from (scene, its params).
  EnergySum(const Scene& scene, const Params& prm) : EnergySum(scene, prm, std::index_sequence_for<Terms...>{}) {}

  void declare(AssemblyPlan& plan) {
    std::apply([&](auto&... t) { (t.declare(plan), ...); }, terms_);
  }
  double energy(const State& s) const {
    return std::apply([&](const auto&... t) { return (0.0 + ... + t.energy(s)); }, terms_);
  }
  void add_gradient(const State& s, Eigen::VectorXd& g) const {
    std::apply([&](const auto&... t) { (t.add_gradient(s, g), ...); }, terms_);
  }
  void add_hessian(const State& s, ElementBuffer& buf, HessianMode mode) const {
    std::apply([&](const auto&... t) { (t.add_hessian(s, buf, mode), ...); }, terms_);
  }
  /// Appends each term's entries, in order.
  void energy_terms(const State& s, EnergyTerms& terms) const {
    std::apply([&](const auto&... t) { (t.energy_terms(s, terms), ...); }, terms_);
  }
  /// True if every term accepts the state.
  bool admissible(const State& s) const {
    return std::apply([&](const auto&... t) { return (true && ... && t.admissible(s)); }, terms_);
  }

  /// Forwards the optional begin_step hook (animated rest states) to the terms that have it.
  void begin_step(const State& s, double t_end) {
    std::apply([&](auto&... t) { (begin_term(t, s, t_end), ...); }, terms_);
  }

  /// Term I (e.g. for statistics or tests).
  template <std::size_t I>
  const auto& term() const {
    return std::get<I>(terms_);
  }
  static constexpr std::size_t size() { return sizeof...(Terms); }

 private:
  template <class Term>
  static void begin_term(Term& t, const State& s, double t_end) {
    if constexpr (HasBeginStep<Term>) t.begin_step(s, t_end);
  }
  template <class Term>
  static void validate_term(const typename Term::Params& p, Checker& c) {
    if constexpr (requires { Term::validate(p); }) c.merge(Term::validate(p));
  }
  template <std::size_t... I>
  EnergySum(const Scene& scene, const Params& prm, std::index_sequence<I...>)
      : terms_(Terms(scene, std::get<I>(prm.terms))...) {}

  std::tuple<Terms...> terms_;
};

static_assert(EnergyModel<EnergySum<StvkMembrane<Isotropic>, HingeBending<ThetaEnergy>, Gravity>>);

}  // namespace weft::models
