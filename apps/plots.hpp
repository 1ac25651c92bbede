#pragma once
/// \file plots.hpp
/// Plots through scripts/weft_plot.py run by Debian's interpreter (/usr/bin/python3, which
/// sees python3-matplotlib; a pyenv or virtualenv python does not). A missing interpreter,
/// script or matplotlib is a message on stderr, never an error: the tables are the results,
/// the plots are views of them.
#include <string>
#include <vector>

namespace weft::app {

enum class PlotOutcome { written, skipped, failed };

/// Runs `weft_plot.py KIND INPUT --out OUT EXTRA...`; says on stderr what was skipped or
/// failed and why.
PlotOutcome plot(const std::string& kind, const std::string& input, const std::string& out,
                 const std::vector<std::string>& extra = {});

/// Runs `/usr/bin/python3 <source tree>/scripts/SCRIPT ARGS...` with its output on ours;
/// returns its exit status (127 when the interpreter or the script is missing, with a message).
int run_python_tool(const std::string& script, const std::vector<std::string>& args);

}  // namespace weft::app
