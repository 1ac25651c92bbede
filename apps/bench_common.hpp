#pragma once
/// \file bench_common.hpp
/// What every `weft bench` report states about where it ran.
#include <string>

namespace weft::app {

/// The CPU's "model name" from /proc/cpuinfo ("unknown" elsewhere).
std::string cpu_model();
/// `git describe --always --dirty` of the source tree ("unknown" without git).
std::string git_describe(const std::string& source_dir);

}  // namespace weft::app
