#pragma once
/// \file error.hpp
/// The three error channels of weft (docs/architecture.md, "Errors"):
///  - configuration errors throw `ConfigError` before any work starts;
///  - numerical outcomes are returned in reports (`Status`, see status.hpp);
///  - broken invariants fail `WEFT_ASSERT` (always on in tests and Debug builds).
#include <fmt/format.h>

#include <stdexcept>
#include <string>
#include <vector>

namespace weft {

/// A scene, parameter or input file that cannot be run. `what()` lists every violation,
/// one per line, each naming the key, the value and what would be valid.
class ConfigError : public std::invalid_argument {
 public:
  explicit ConfigError(const std::string& message) : std::invalid_argument(message) {}
  ConfigError(std::string header, std::vector<std::string> violations)
      : std::invalid_argument(join(header, violations)), violations_(std::move(violations)) {}
  /// The individual violations (empty when constructed from a single message).
  const std::vector<std::string>& violations() const { return violations_; }

 private:
  static std::string join(const std::string& header, const std::vector<std::string>& v) {
    std::string s = header;
    for (const auto& line : v) s += "\n  " + line;
    return s;
  }
  std::vector<std::string> violations_;
};

/// A violated internal invariant: a bug in weft, not in the user's input.
class InvariantError : public std::logic_error {
 public:
  using std::logic_error::logic_error;
};

}  // namespace weft

#if defined(NDEBUG) && !defined(WEFT_ENABLE_ASSERTS)
#define WEFT_ASSERT(cond, ...) ((void)0)
#else
#define WEFT_ASSERT(cond, ...)                                                               \
  do {                                                                                       \
    if (!(cond))                                                                             \
      throw ::weft::InvariantError(fmt::format("{}:{}: assertion '{}' failed: {}", __FILE__, \
                                               __LINE__, #cond, fmt::format(__VA_ARGS__)));  \
  } while (false)
#endif
