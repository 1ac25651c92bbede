#pragma once
/// \file validate.hpp
/// `weft validate`: reference problems with a closed-form or numerically exact answer
/// (apps/references.hpp), each run as a scene and measured: a table (problem, reference,
/// measured, relative error, pass) on stdout, validate.csv, validate.json and report.md in the
/// output directory (docs/validation.md).
#include <string>
#include <vector>

namespace weft::app {

struct ValidateOptions {
  bool quick = false;                  ///< the reduced suite (coarse meshes; the default tests run it)
  std::vector<std::string> only;       ///< run the problems whose name starts with one of these ("" = all)
  std::vector<std::string> overrides;  ///< key=value applied to every problem's scene (cloths.* only to cloths, rods.* only to rods)
  std::string out_dir = "out-validate";
  bool plots = true;
  bool quiet = false;
};

struct ValidationRow {
  std::string problem, quantity, unit, source;
  double reference = 0, measured = 0;
  double error = 0;       ///< |measured - reference| / |reference|, or |measured| for a zero reference
  double tolerance = 0;   ///< on `error`
  bool absolute = false;  ///< error is absolute (reference 0)
  bool pass = false;
  std::string status = "ok";  ///< "ok", or "failed at step N (stage): why"
  int steps = 0;
  double seconds = 0;
};

/// Exit status when every run ended but a problem missed its tolerance.
inline constexpr int exit_validation_missed = 4;

/// Runs the suite; returns 0 when every problem passes, 2 for a configuration error before any
/// run, 3 when a run failed, exit_validation_missed when a measurement missed its tolerance.
int run_validate(const ValidateOptions& options, std::vector<ValidationRow>* rows = nullptr);

/// The problem names of the suite (`quick`: the reduced one).
std::vector<std::string> validation_problems(bool quick);

}  // namespace weft::app
