#pragma once
/// \file any_simulator.hpp
/// Type erasure at the top only: the command line and ablations pick a pre-built
/// combination at run time; every hot loop stays inside the concrete `Simulator`.
#include <memory>
#include <string>
#include <string_view>

#include "framework/checkpoint.hpp"
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
  /// "" when this combination writes and reads checkpoints (framework/checkpoint.hpp); else why not.
  virtual std::string checkpoint_unsupported() const = 0;
  /// The state between two steps, to the bit (header: "kind", "step", "time", sizes, "combo").
  /// Throws ConfigError when checkpoint_unsupported() is not empty.
  virtual Checkpoint checkpoint() const = 0;
  /// Continue from a checkpoint. Throws ConfigError (state unchanged) when it does not fit
  /// this scene, or when checkpoint_unsupported() is not empty.
  virtual void restore(const Checkpoint& c) = 0;
};

/// A simulator that writes and reads checkpoints.
template <class Sim>
concept Checkpointable = requires(const Sim& s, Sim& m, Checkpoint& c) {
  s.save(c);
  m.restore(c);
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
  std::string checkpoint_unsupported() const override {
    if constexpr (Checkpointable<Sim>)
      return "";
    else
      return fmt::format("combination {} does not write checkpoints: one of its policies keeps state between steps without "
                         "saving it (framework/checkpoint.hpp: declare it stateless, or give it save and restore)",
                         combo_);
  }
  Checkpoint checkpoint() const override {
    if constexpr (Checkpointable<Sim>) {
      Checkpoint c;
      sim_.save(c);
      c.header["combo"] = std::string(combo_);
      return c;
    } else {
      throw ConfigError(checkpoint_unsupported());
    }
  }
  void restore(const Checkpoint& c) override {
    if constexpr (Checkpointable<Sim>)
      sim_.restore(c);
    else
      throw ConfigError(checkpoint_unsupported());
  }
  Sim& simulator() { return sim_; }

 private:
  std::string_view combo_;
  Sim sim_;
};

}  // namespace weft
