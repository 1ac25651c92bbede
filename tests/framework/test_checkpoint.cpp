// The checkpoint file (framework/checkpoint.hpp): values come back to the bit, and a file
// that is not a checkpoint, of another format or cut short is refused with a message that
// names the file and what is wrong.
#include <doctest/doctest.h>

#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>

#include "framework/checkpoint.hpp"
#include "framework/error.hpp"

using namespace weft;

namespace {
std::filesystem::path scratch(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() / ("weft_checkpoint_" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  return dir / name;
}
std::string refusal(const std::string& path) {
  try {
    read_checkpoint(path);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}
}  // namespace

TEST_CASE("checkpoint: arrays and header come back bitwise with subnormals and signed zeros and infinities") {
  Checkpoint c;
  c.header["kind"] = "rods";
  c.header["time"] = 0.1 + 0.2;  // 0.30000000000000004
  c.header["step"] = 300;
  const std::vector<double> odd = {0.1, -0.0, std::numeric_limits<double>::denorm_min(), std::numeric_limits<double>::max(),
                                   std::numeric_limits<double>::infinity(), std::nextafter(1.0, 2.0), -1e-300};
  c.put("odd", odd);
  Eigen::VectorXd r = Eigen::VectorXd::Random(1001);
  c.put("random", r);
  c.put("empty", std::vector<double>{});
  const auto path = scratch("a.wckp").string();
  write_checkpoint(path, c);
  const Checkpoint d = read_checkpoint(path);
  CHECK(d.header["kind"] == "rods");
  CHECK(d.header["step"] == 300);
  CHECK(d.header["time"].get<double>() == 0.1 + 0.2);
  REQUIRE(d.arrays.size() == 3);
  CHECK(d.arrays[0].first == "odd");  // file order
  const auto& o = d.get("odd", 7);
  CHECK(std::memcmp(o.data(), odd.data(), odd.size() * sizeof(double)) == 0);
  CHECK(std::signbit(o[1]));
  const auto& q = d.get("random");
  CHECK(Eigen::Map<const Eigen::VectorXd>(q.data(), 1001) == r);
  CHECK(d.get("empty").empty());
  // The reader's own keys do not leak into the header.
  CHECK(!d.header.contains("arrays"));
  CHECK(!d.header.contains("format"));
  // A size the caller needs that the file does not hold is named.
  CHECK_THROWS_WITH_AS(d.get("random", 1000), "checkpoint array 'random' holds 1001 values; this scene needs 1000", ConfigError);
  CHECK_THROWS_WITH_AS(d.get("velocities"), "checkpoint has no array 'velocities'", ConfigError);
}

TEST_CASE("checkpoint: a missing or foreign or newer or truncated file is refused naming the file and the fault") {
  Checkpoint c;
  c.header["step"] = 1;
  c.put("q", std::vector<double>(100, 1.5));
  const auto good = scratch("good.wckp").string();
  write_checkpoint(good, c);
  std::string bytes;
  {
    std::ifstream in(good, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  REQUIRE(bytes.size() > 800);
  CHECK(refusal(good).empty());  // the guard: the intact file reads
  const auto write = [&](const std::string& name, const std::string& text) {
    const auto p = scratch(name).string();
    std::ofstream(p, std::ios::binary) << text;
    return p;
  };
  const auto check = [](const std::string& message, const std::string& path, const std::string& fault) {
    INFO(message);
    CHECK(message.find(path) != std::string::npos);
    CHECK(message.find(fault) != std::string::npos);
  };
  const auto none = scratch("none.wckp").string();
  check(refusal(none), none, "file not found");
  const auto foreign = write("foreign.wckp", "{\"step\": 1}\n");
  check(refusal(foreign), foreign, "not a weft checkpoint");
  const auto cut_data = write("cut_data.wckp", bytes.substr(0, bytes.size() - 8));
  check(refusal(cut_data), cut_data, "truncated data: array 'q' should hold 100 values, the file has room for 99");
  const auto cut_header = write("cut_header.wckp", bytes.substr(0, 30));
  check(refusal(cut_header), cut_header, "truncated or corrupt header length");
  const auto trailing = write("trailing.wckp", bytes + "x");
  check(refusal(trailing), trailing, "trailing bytes");
  std::string newer = bytes;
  const auto at = newer.find("\"format\":1");
  REQUIRE(at != std::string::npos);
  newer[at + 9] = '7';
  const auto future = write("future.wckp", newer);
  check(refusal(future), future, "format 7 is not supported (this build reads format 1)");
}
