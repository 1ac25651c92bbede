#include <doctest/doctest.h>

#include "framework/params_json.hpp"
#include "framework/scene.hpp"
#include "framework/units.hpp"

using namespace weft;

namespace {
enum class Flavour { plain, fancy };
constexpr std::array<std::string_view, 2> flavour_names = {"plain", "fancy"};
struct Inner {
  double stiffness = 1.0;
  template <class V>
  void visit(V& v) { v.field("stiffness", stiffness, {Unit::pressure, Range::gt(0), "a stiffness"}); }
};
struct Outer {
  double length = 1.0;
  int count = 3;
  bool enabled = true;
  Flavour flavour = Flavour::plain;
  Eigen::Vector3d direction{0, 0, 1};
  std::optional<double> maybe;
  Inner inner;
  template <class V>
  void visit(V& v) {
    v.field("length", length, {Unit::length, Range::gt(0), "a length"});
    v.field("count", count, {Unit::none, Range::closed(1, 10), "a count"});
    v.field("enabled", enabled, {Unit::none, Range::any(), "a flag"});
    v.choice("flavour", flavour, flavour_names, "a choice");
    v.field("direction", direction, {Unit::none, Range::any(), "a vector"});
    v.field("maybe", maybe, {Unit::time, Range::ge(0), "optional"});
    v.section("inner", inner);
  }
};
}  // namespace

TEST_SUITE("framework") {
  TEST_CASE("params: every violation is reported at once / with key path / value and valid range") {
    const Json j = Json::parse(R"({"length": -2, "count": 11, "enabled": "yes", "flavour": "spicy",
                                   "direction": [1, 2], "inner": {"stiffness": "3 mm", "extra": 1}, "typo": 0})");
    try {
      read_params<Outer>(j, "thing", "bad thing:");
      FAIL("expected a ConfigError");
    } catch (const ConfigError& e) {
      const auto& v = e.violations();
      CAPTURE(e.what());
      CHECK(v.size() == 8);
      const std::string all = e.what();
      CHECK(all.find("thing.length = -2 m is out of range: valid > 0 m") != std::string::npos);
      CHECK(all.find("thing.count = 11 is out of range: valid in [1, 10]") != std::string::npos);
      CHECK(all.find("thing.enabled = \"yes\" has the wrong type: expected true or false") != std::string::npos);
      CHECK(all.find("thing.flavour = \"spicy\" is not a valid choice: valid are plain, fancy") != std::string::npos);
      CHECK(all.find("thing.direction = [1,2] has the wrong type") != std::string::npos);
      CHECK(all.find("thing.inner.stiffness = \"3 mm\": unit 'mm' is a length, expected a pressure") != std::string::npos);
      CHECK(all.find("thing.inner.extra is not a known key") != std::string::npos);
      CHECK(all.find("thing.typo is not a known key") != std::string::npos);
    }
  }

  TEST_CASE("params: valid values / units and defaults") {
    const Json j = Json::parse(R"({"length": "25 cm", "flavour": "fancy", "maybe": "5 ms", "inner": {"stiffness": "2 kPa"}})");
    const Outer o = read_params<Outer>(j, "", "bad:");
    CHECK(o.length == doctest::Approx(0.25));
    CHECK(o.count == 3);
    CHECK(o.flavour == Flavour::fancy);
    CHECK(o.maybe.value() == doctest::Approx(0.005));
    CHECK(o.inner.stiffness == doctest::Approx(2000));
    const Json back = write_params(o);
    CHECK(back["flavour"] == "fancy");
    CHECK(back["inner"]["stiffness"].get<double>() == doctest::Approx(2000));
    CHECK(read_params<Outer>(back, "", "bad:").length == doctest::Approx(0.25));
  }

  TEST_CASE("units: conversions and errors") {
    std::string err;
    CHECK(parse_quantity("20 MPa", Unit::pressure, err).value() == doctest::Approx(2e7));
    CHECK(parse_quantity("150 g/m^2", Unit::area_density, err).value() == doctest::Approx(0.15));
    CHECK(parse_quantity("981 cm/s^2", Unit::acceleration, err).value() == doctest::Approx(9.81));
    CHECK(parse_quantity("90 deg", Unit::angle, err).value() == doctest::Approx(M_PI / 2));
    CHECK(parse_quantity("1e3 dyn/cm^2", Unit::pressure, err).value() == doctest::Approx(100.0));
    CHECK(parse_quantity(" 0.5 ", Unit::length, err).value() == doctest::Approx(0.5));
    CHECK_FALSE(parse_quantity("3 furlongs", Unit::length, err));
    CHECK(err.find("unknown unit 'furlongs'") != std::string::npos);
    CHECK_FALSE(parse_quantity("abc", Unit::length, err));
    CHECK_FALSE(parse_quantity("2 s", Unit::length, err));
    CHECK(err.find("is a time, expected a length") != std::string::npos);
  }

  TEST_CASE("checker: collects cross-field violations") {
    Checker c("integrator");
    c.require(false, "a", 1, "> 2").require(true, "b", 0, "any").require(false, "c", "x", "y");
    CHECK(c.violations().size() == 2);
    CHECK(c.violations()[0] == "integrator.a = 1 violates '> 2'");
    CHECK_THROWS_AS(c.throw_if_failed(), ConfigError);
  }

  TEST_CASE("overrides: dotted keys mirror the tree - arrays by index - malformed rejected") {
    Json doc = Json::parse(R"({"time": {"dt": 0.01}, "cloths": [{"material": {"thickness": 1}}]})");
    apply_override(doc, "time.dt=0.002");
    apply_override(doc, "cloths.0.material.thickness=\"0.5 mm\"");
    apply_override(doc, "gravity=[0,0,-1]");
    apply_override(doc, "integrator.line_search=backtracking");
    CHECK(doc["time"]["dt"].get<double>() == doctest::Approx(0.002));
    CHECK(doc["cloths"][0]["material"]["thickness"] == "0.5 mm");
    CHECK(doc["gravity"].size() == 3);
    CHECK(doc["integrator"]["line_search"] == "backtracking");
    CHECK_THROWS_WITH_AS(apply_override(doc, "time.dt"), doctest::Contains("key=value"), ConfigError);
    CHECK_THROWS_WITH_AS(apply_override(doc, "cloths.3.name=x"), doctest::Contains("not an index"), ConfigError);
    CHECK_THROWS_WITH_AS(apply_override(doc, "time.dt.x=1"), doctest::Contains("is a value, not a section"), ConfigError);
  }
}
