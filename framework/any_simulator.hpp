#pragma once
/// \file any_simulator.hpp
/// Type erasure at the top only: the command line and ablations pick a pre-built
/// combination at run time; every hot loop stays inside the concrete `Simulator`.
#include <memory>
#include <string>
#include <string_view>

#include "framework/params_json.hpp"
#include "framework/simulator.hpp"

namespace weft {

class AnySimulator {
 public:
  virtual ~AnySimulator() = default;
  virtual StepReport step() = 0;
  virtual const State& state() const = 0;
  virtual const Scene& scene() const = 0;
  virtual EnergyReport energies() const = 0;
  virtual Eigen::VectorXd potential_gradient() const = 0;
  /// Effective parameters (SI), as a JSON tree mirroring the scene's solver sections.
  virtual Json params() const = 0;
  virtual std::string_view combo() const = 0;
};

template <class Sim>
class SimulatorAdapter final : public AnySimulator {
 public:
  SimulatorAdapter(std::string_view combo, Scene scene, const typename Sim::Params& prm)
      : combo_(combo), sim_(std::move(scene), prm) {}
  StepReport step() override { return sim_.step(); }
  const State& state() const override { return sim_.state(); }
  const Scene& scene() const override { return sim_.scene(); }
  EnergyReport energies() const override { return sim_.energies(); }
  Eigen::VectorXd potential_gradient() const override { return sim_.potential_gradient(); }
  Json params() const override { return write_params(sim_.params()); }
  std::string_view combo() const override { return combo_; }
  Sim& simulator() { return sim_; }

 private:
  std::string_view combo_;
  Sim sim_;
};

}  // namespace weft
