#pragma once
/// Command-line helpers of the weft command (apps/main.cpp).
#include <string>
#include <vector>

namespace weft::app {

/// The most worker threads `--threads` accepts.
inline constexpr int max_threads = 1024;

/// argv in the order CLI11's App::parse(std::vector<std::string>&) takes (reversed, without the
/// program name), with every `key=value` override that follows the values of a list option
/// (`--combos a b`, `--dt 1e-3 1e-2`, ...) moved in front of that option: a list option's values
/// are names and numbers, never overrides, so `--combos applicable time.dt=0.01 --duration 1` passes
/// `time.dt=0.01` to the command's overrides instead of reading it as a combination.
std::vector<std::string> overrides_out_of_lists(int argc, const char* const* argv);

}  // namespace weft::app
