#pragma once
/// \file params.hpp
/// Parameters: every `Params` struct describes its fields once, in a `visit` member:
///
///     template <class V> void visit(V& v) {
///       v.field("youngs_modulus", youngs_modulus, {Unit::pressure, Range::gt(0), "Young's modulus"});
///       v.choice("line_search", line_search, line_search_names, "line search on the merit");
///       v.section("newton", newton);
///     }
///
/// The same description drives reading scene files (params_json.hpp: unknown keys, wrong
/// types and out-of-range values are all reported at once), writing the effective
/// parameters into run summaries, and generating the scene reference document. Checks
/// that involve several fields go in a `validate` function that fills a `Checker`.
#include <fmt/format.h>

#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include "framework/error.hpp"
#include "framework/units.hpp"

namespace weft {

/// A closed, open or half-open interval of admissible values.
struct Range {
  double lo = -std::numeric_limits<double>::infinity();
  double hi = std::numeric_limits<double>::infinity();
  bool lo_open = false, hi_open = false;

  static Range any() { return {}; }
  static Range gt(double a) { return {a, std::numeric_limits<double>::infinity(), true, false}; }
  static Range ge(double a) { return {a, std::numeric_limits<double>::infinity(), false, false}; }
  static Range closed(double a, double b) { return {a, b, false, false}; }
  static Range open(double a, double b) { return {a, b, true, true}; }
  static Range closed_open(double a, double b) { return {a, b, false, true}; }
  static Range open_closed(double a, double b) { return {a, b, true, false}; }

  bool contains(double x) const {
    if (!(x == x)) return false;  // NaN
    const bool lo_ok = lo_open ? x > lo : x >= lo;
    const bool hi_ok = hi_open ? x < hi : x <= hi;
    return lo_ok && hi_ok;
  }
  bool unbounded() const { return lo == -std::numeric_limits<double>::infinity() && hi == std::numeric_limits<double>::infinity(); }
  /// "> 0", ">= 1", "in (0, 1]", "any".
  std::string text() const {
    const bool lo_inf = lo == -std::numeric_limits<double>::infinity();
    const bool hi_inf = hi == std::numeric_limits<double>::infinity();
    if (lo_inf && hi_inf) return "any";
    if (hi_inf) return fmt::format("{} {}", lo_open ? ">" : ">=", lo);
    if (lo_inf) return fmt::format("{} {}", hi_open ? "<" : "<=", hi);
    return fmt::format("in {}{}, {}{}", lo_open ? "(" : "[", lo, hi, hi_open ? ")" : "]");
  }
};

/// What a field means: its unit (values are SI inside weft), admissible range, and a
/// one-line description for the reference document.
struct FieldInfo {
  Unit unit = Unit::none;
  Range range = {};
  const char* doc = "";
  bool required = false;  ///< no safe default: the scene must give it
};

/// Collects violations of cross-field conditions; `throw_if_failed` reports all at once.
class Checker {
 public:
  explicit Checker(std::string path = {}) : path_(std::move(path)) {}
  template <class T>
  Checker& require(bool ok, std::string_view key, const T& value, std::string_view valid) {
    if (!ok) violations_.push_back(fmt::format("{}{}{} = {} violates '{}'", path_, path_.empty() ? "" : ".", key, value, valid));
    return *this;
  }
  /// A violation that is not about one value.
  Checker& fail(std::string message) {
    violations_.push_back(path_.empty() ? std::move(message) : fmt::format("{}: {}", path_, message));
    return *this;
  }
  Checker& merge(const Checker& o) {
    violations_.insert(violations_.end(), o.violations_.begin(), o.violations_.end());
    return *this;
  }
  bool ok() const { return violations_.empty(); }
  const std::vector<std::string>& violations() const { return violations_; }
  const std::string& path() const { return path_; }
  void throw_if_failed(std::string_view header = "Invalid configuration:") const {
    if (!ok()) throw ConfigError(std::string(header), violations_);
  }

 private:
  std::string path_;
  std::vector<std::string> violations_;
};

/// Name of an enum value from its names table (enum values index the table).
template <class E, size_t N>
std::string_view enum_name(E value, const std::array<std::string_view, N>& names) {
  const auto i = static_cast<size_t>(value);
  return i < N ? names[i] : std::string_view("?");
}

}  // namespace weft
