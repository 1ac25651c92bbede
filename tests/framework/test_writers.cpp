// Rod frames as polylines: one OBJ `l` element and one VTK line per rod, over the stacked
// vertices; the triangle writer shares the VTK points block.
#include <doctest/doctest.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "framework/writers.hpp"

using namespace weft;

namespace {
std::string slurp(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}
}  // namespace

TEST_CASE("writers: rods are written as one polyline each in OBJ and VTK") {
  const auto dir = std::filesystem::temp_directory_path() / ("weft_writers_" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  Eigen::VectorXd x(3 * 5), v = Eigen::VectorXd::Ones(3 * 5);
  for (int i = 0; i < 5; ++i) x.segment<3>(3 * i) = Eigen::Vector3d(i, 0.5 * i, 0);
  const std::vector<int> first = {0, 3, 5};  // rods of 3 and 2 vertices
  write_polylines_obj((dir / "r.obj").string(), x, first, "two rods");
  const std::string obj = slurp(dir / "r.obj");
  CHECK(obj.find("l 1 2 3\n") != std::string::npos);
  CHECK(obj.find("l 4 5\n") != std::string::npos);
  CHECK(obj.find("v 4 2 0\n") != std::string::npos);
  write_polylines_vtp((dir / "r.vtp").string(), x, first, &v);
  const std::string vtp = slurp(dir / "r.vtp");
  CHECK(vtp.find("NumberOfPoints=\"5\" NumberOfVerts=\"0\" NumberOfLines=\"2\"") != std::string::npos);
  CHECK(vtp.find("Name=\"offsets\" format=\"ascii\">\n3 5 \n") != std::string::npos);
  CHECK(vtp.find("Name=\"velocity\"") != std::string::npos);
  Eigen::MatrixX3i F(1, 3);
  F << 0, 1, 2;
  write_vtp((dir / "t.vtp").string(), x.head(9), F);
  const std::string tri = slurp(dir / "t.vtp");
  CHECK(tri.find("NumberOfPoints=\"3\" NumberOfVerts=\"0\" NumberOfLines=\"0\" NumberOfStrips=\"0\" NumberOfPolys=\"1\"") != std::string::npos);
  CHECK(tri.find("Name=\"velocity\"") == std::string::npos);
  std::filesystem::remove_all(dir);
}
