#include "framework/units.hpp"

#include <fmt/format.h>

#include <array>
#include <charconv>
#include <cmath>
#include <numbers>

namespace weft {
namespace {

struct UnitDef {
  std::string_view symbol;
  Unit dim;
  double factor;  // SI value of 1 symbol
};

constexpr double deg = std::numbers::pi / 180.0;
constexpr std::array<UnitDef, 45> table{{
    {"m", Unit::length, 1.0},          {"cm", Unit::length, 1e-2},        {"mm", Unit::length, 1e-3},
    {"um", Unit::length, 1e-6},        {"km", Unit::length, 1e3},         {"m^2", Unit::area, 1.0},
    {"cm^2", Unit::area, 1e-4},        {"mm^2", Unit::area, 1e-6},        {"kg/m^2", Unit::area_density, 1.0},
    {"g/m^2", Unit::area_density, 1e-3}, {"g/cm^2", Unit::area_density, 10.0}, {"Pa", Unit::pressure, 1.0},
    {"N/m^2", Unit::pressure, 1.0},    {"kPa", Unit::pressure, 1e3},      {"MPa", Unit::pressure, 1e6},
    {"GPa", Unit::pressure, 1e9},      {"dyn/cm^2", Unit::pressure, 0.1}, {"Ba", Unit::pressure, 0.1},
    {"s", Unit::time, 1.0},            {"ms", Unit::time, 1e-3},          {"us", Unit::time, 1e-6},
    {"1/s", Unit::frequency, 1.0},     {"Hz", Unit::frequency, 1.0},      {"m/s", Unit::velocity, 1.0},
    {"cm/s", Unit::velocity, 1e-2},    {"mm/s", Unit::velocity, 1e-3},    {"km/h", Unit::velocity, 1.0 / 3.6},
    {"m/s^2", Unit::acceleration, 1.0}, {"cm/s^2", Unit::acceleration, 1e-2}, {"g0", Unit::acceleration, 9.80665},
    {"rad", Unit::angle, 1.0},         {"deg", Unit::angle, deg},         {"rad/s", Unit::angular_velocity, 1.0},
    {"deg/s", Unit::angular_velocity, deg}, {"rpm", Unit::angular_velocity, 2 * std::numbers::pi / 60.0},
    {"J", Unit::energy, 1.0},          {"N m", Unit::energy, 1.0},        {"erg", Unit::energy, 1e-7},
    {"kg", Unit::mass, 1.0},           {"g", Unit::mass, 1e-3},           {"kg/m^3", Unit::density, 1.0},
    {"g/cm^3", Unit::density, 1e3},    {"Pa s", Unit::viscosity, 1.0},    {"P", Unit::viscosity, 0.1},
    {"g/(cm s)", Unit::viscosity, 0.1},
}};

std::string_view trim(std::string_view s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front()))) s.remove_prefix(1);
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.remove_suffix(1);
  return s;
}

}  // namespace

std::string_view si_symbol(Unit u) {
  switch (u) {
    case Unit::none: return "";
    case Unit::length: return "m";
    case Unit::area: return "m^2";
    case Unit::area_density: return "kg/m^2";
    case Unit::pressure: return "Pa";
    case Unit::time: return "s";
    case Unit::frequency: return "1/s";
    case Unit::velocity: return "m/s";
    case Unit::acceleration: return "m/s^2";
    case Unit::angle: return "rad";
    case Unit::angular_velocity: return "rad/s";
    case Unit::energy: return "J";
    case Unit::mass: return "kg";
    case Unit::density: return "kg/m^3";
    case Unit::viscosity: return "Pa s";
  }
  return "";
}

std::string_view dimension_name(Unit u) {
  switch (u) {
    case Unit::none: return "dimensionless";
    case Unit::length: return "length";
    case Unit::area: return "area";
    case Unit::area_density: return "mass per area";
    case Unit::pressure: return "pressure";
    case Unit::time: return "time";
    case Unit::frequency: return "frequency";
    case Unit::velocity: return "velocity";
    case Unit::acceleration: return "acceleration";
    case Unit::angle: return "angle";
    case Unit::angular_velocity: return "angular velocity";
    case Unit::energy: return "energy";
    case Unit::mass: return "mass";
    case Unit::density: return "density";
    case Unit::viscosity: return "viscosity";
  }
  return "";
}

std::string accepted_units(Unit u) {
  std::string s;
  for (const auto& d : table)
    if (d.dim == u) s += (s.empty() ? "" : ", ") + std::string(d.symbol);
  return s.empty() ? "none (a plain number)" : s;
}

std::optional<double> parse_quantity(std::string_view text, Unit expected, std::string& error) {
  text = trim(text);
  double value = 0;
  const auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || !std::isfinite(value)) {
    error = fmt::format("'{}' is not a number with a unit", text);
    return std::nullopt;
  }
  const std::string_view unit = trim(text.substr(ptr - text.data()));
  if (unit.empty()) return value;  // a bare number in a string: SI
  for (const auto& d : table) {
    if (d.symbol != unit) continue;
    if (d.dim != expected) {
      error = fmt::format("unit '{}' is a {}, expected a {} ({})", unit, dimension_name(d.dim),
                          dimension_name(expected), accepted_units(expected));
      return std::nullopt;
    }
    return value * d.factor;
  }
  error = fmt::format("unknown unit '{}' (accepted for {}: {})", unit, dimension_name(expected), accepted_units(expected));
  return std::nullopt;
}

}  // namespace weft
