// The test suite's own hygiene: ctest runs each doctest case by name (doctest_discover_tests,
// tests/CMakeLists.txt), and a name with ';' becomes two ctest tests that match no case and
// pass without running anything, while a name with ',' loses its suite label, so a "slow"
// case runs in the default suite instead (found on 2026-11-29: a 90 s hair-ball case ran
// there). Every TEST_CASE name under tests/ must be free of both.
#include <doctest/doctest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>

TEST_CASE("test names: no TEST_CASE name holds a comma or a semicolon (ctest would split it or drop its label)") {
  const char* root = std::getenv("WEFT_SOURCE_DIR");
  REQUIRE_MESSAGE(root != nullptr, "WEFT_SOURCE_DIR is not set");
  const std::regex test_case(R"re(TEST_CASE\("((?:[^"\\]|\\.)*)")re");
  int cases = 0;
  for (const auto& e : std::filesystem::recursive_directory_iterator(std::filesystem::path(root) / "tests")) {
    if (!e.is_regular_file() || e.path().extension() != ".cpp") continue;
    std::ifstream in(e.path());
    std::stringstream text;
    text << in.rdbuf();
    const std::string s = text.str();
    for (auto it = std::sregex_iterator(s.begin(), s.end(), test_case); it != std::sregex_iterator(); ++it) {
      const std::string name = (*it)[1];
      ++cases;
      CAPTURE(e.path().filename().string());
      CHECK_MESSAGE(name.find_first_of(",;") == std::string::npos, name);
    }
  }
  CHECK(cases > 400);  // the scan found the suite's cases
}
