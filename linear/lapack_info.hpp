#pragma once
/// \file lapack_info.hpp
/// Which LAPACK the rods' banded solves (BandedLu: dgbtrf / dgbtrs) run on. Debian selects
/// liblapack.so.3 through its alternatives (reference LAPACK, or OpenBLAS once
/// libopenblas0-pthread is installed), and the two round differently: a chaotic run (a hair
/// ball, a whip over thousands of steps) then takes another path. Runs record it next to the
/// hardware.
#include <string>

namespace weft::linear {

/// The resolved path of the shared library that provides dgbtrf_ (e.g.
/// /usr/lib/x86_64-linux-gnu/openblas-pthread/liblapack.so.3), or "unknown".
std::string lapack_library();

}  // namespace weft::linear
