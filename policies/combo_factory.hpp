#pragma once
/// \file combo_factory.hpp
/// Shared body of the per-combination factories (one per file in policies/combos/).
#include <memory>

#include "framework/any_simulator.hpp"
#include "framework/params_json.hpp"
#include "policies/registry.hpp"

namespace weft::detail {

template <class Sim>
std::unique_ptr<AnySimulator> make_combo(std::string_view key, const Scene& scene) {
  using P = typename Sim::Params;
  const std::string header = fmt::format("{}: invalid solver parameters for combo '{}'", scene.path, key);
  P prm = read_params<P>(scene.solver, "", header);
  const Checker c = P::validate(prm);
  if (!c.ok()) throw ConfigError(header, c.violations());
  return std::make_unique<SimulatorAdapter<Sim>>(key, scene, prm);
}

template <class Policy>
PolicyDoc policy_doc(const char* section) {
  PolicyDoc d{section, std::string(Policy::name), {}};
  typename Policy::Params p{};
  DocWriter w(section, d.rows);
  p.visit(w);
  return d;
}

template <class Sim>
std::vector<PolicyDoc> combo_docs() {
  return {policy_doc<typename Sim::EnergyType>("energy"), policy_doc<typename Sim::IntegratorType>("integrator"),
          policy_doc<typename Sim::ContactType>("contact"), policy_doc<typename Sim::LinearType>("linear")};
}

template <class Sim>
std::vector<PolicyDoc> rod_combo_docs() {
  return {policy_doc<typename Sim::IntegratorType>("integrator"), policy_doc<typename Sim::ContactType>("contact")};
}

}  // namespace weft::detail

/// Defines the factory and docs functions of a combination in its own translation unit,
/// next to the explicit instantiation of its simulator type:
///   template class Simulator<...>;
///   WEFT_DEFINE_COMBO(cloth_ip_direct, Simulator<...>)
/// (the key must match the row of WEFT_COMBO_TABLE in registry.cpp).
#define WEFT_DEFINE_COMBO(key, ...)                                                                                \
  namespace combo_factories {                                                                                      \
  std::unique_ptr<AnySimulator> make_##key(const Scene& scene) { return detail::make_combo<__VA_ARGS__>(#key, scene); } \
  std::vector<PolicyDoc> docs_##key() { return detail::combo_docs<__VA_ARGS__>(); }                                \
  }

/// The same for a rod combination (its sections: integrator and contact).
#define WEFT_DEFINE_ROD_COMBO(key, ...)                                                                            \
  namespace combo_factories {                                                                                      \
  std::unique_ptr<AnySimulator> make_##key(const Scene& scene) { return detail::make_combo<__VA_ARGS__>(#key, scene); } \
  std::vector<PolicyDoc> docs_##key() { return detail::rod_combo_docs<__VA_ARGS__>(); }                            \
  }
