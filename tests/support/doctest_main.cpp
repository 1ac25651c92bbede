// doctest's main, built once. Tests that call weft's drivers in process (plots, default scenes)
// find weft's data in the source tree, whose scripts/ and scenes/ have the layout of an
// installed PREFIX/share/weft: WEFT_DATA_DIR defaults to WEFT_SOURCE_DIR, which CTest sets.
#define DOCTEST_CONFIG_IMPLEMENT
#include <doctest/doctest.h>

#include <cstdlib>

int main(int argc, char** argv) {
  if (const char* src = std::getenv("WEFT_SOURCE_DIR"); src && !std::getenv("WEFT_DATA_DIR")) setenv("WEFT_DATA_DIR", src, 0);
  return doctest::Context(argc, argv).run();
}
