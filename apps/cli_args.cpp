#include "apps/cli_args.hpp"

#include <algorithm>
#include <array>
#include <string_view>

namespace weft::app {
namespace {

// The list options whose values are names or numbers, never key=value overrides (--sa and --vary
// take KEY=VALUE values and are not listed; --solvers entries are name:KEY=VALUE, never matched).
constexpr std::array<std::string_view, 8> list_options = {"--combos",   "--dt",    "--strategies",    "--resolutions",
                                                          "--examples", "--sizes", "--tessellations", "--solvers"};

bool is_override(std::string_view a) {
  const auto eq = a.find('=');
  if (eq == std::string_view::npos || eq == 0 || a.front() == '-') return false;
  const std::string_view key = a.substr(0, eq);
  return std::all_of(key.begin(), key.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' || c == '.';
  });
}

}  // namespace

std::vector<std::string> overrides_out_of_lists(int argc, const char* const* argv) {
  std::vector<std::string> args;
  std::ptrdiff_t list_at = -1;  // index in args of the list option being read, -1: none
  for (int i = 1; i < argc; ++i) {
    const std::string_view a = argv[i];
    if (a == "--") {  // everything after it is positional, as CLI11 has it
      for (; i < argc; ++i) args.emplace_back(argv[i]);
      break;
    }
    if (!a.empty() && a.front() == '-') {
      list_at =
          std::find(list_options.begin(), list_options.end(), a) != list_options.end() ? static_cast<std::ptrdiff_t>(args.size()) : -1;
      args.emplace_back(a);
      continue;
    }
    if (list_at >= 0 && is_override(a)) {
      args.insert(args.begin() + list_at, std::string(a));
      ++list_at;
      continue;
    }
    args.emplace_back(a);
  }
  std::reverse(args.begin(), args.end());
  return args;
}

}  // namespace weft::app
