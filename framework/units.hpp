#pragma once
/// \file units.hpp
/// Physical quantities in scene files: a plain number is SI; a string "<number> <unit>"
/// (e.g. "20 MPa", "0.3 mm", "150 g/m^2", "981 cm/s^2") is converted to SI at the scene
/// boundary. A unit of the wrong dimension is a configuration error.
#include <optional>
#include <string>
#include <string_view>

namespace weft {

enum class Unit {
  none,              ///< dimensionless
  length,            ///< m
  area,              ///< m^2
  area_density,      ///< kg/m^2
  pressure,          ///< Pa (also N/m^2)
  time,              ///< s
  frequency,         ///< 1/s
  velocity,          ///< m/s
  acceleration,      ///< m/s^2
  angle,             ///< rad
  angular_velocity,  ///< rad/s
  energy,            ///< J (also N m: bending stiffness)
  mass,              ///< kg
  density,           ///< kg/m^3
  viscosity,         ///< Pa s (dynamic viscosity)
};

/// SI symbol of a unit ("" for none).
std::string_view si_symbol(Unit u);
/// Human name of a dimension ("length", "pressure", ...).
std::string_view dimension_name(Unit u);

/// Parse "<number> [unit]" for a quantity of dimension `expected`; returns the SI value.
/// On failure returns nullopt and sets `error` to a message that lists the accepted units.
std::optional<double> parse_quantity(std::string_view text, Unit expected, std::string& error);

/// Units accepted for a dimension, comma-separated (for messages and the reference doc).
std::string accepted_units(Unit u);

}  // namespace weft
