#pragma once
/// \file reports.hpp
/// JSON form of the reports (one line of stats.jsonl per step).
#include "framework/params_json.hpp"
#include "framework/status.hpp"

namespace weft {

Json to_json(const LinearReport& r);
Json to_json(const NewtonReport& r, bool with_history = true);
Json to_json(const ContactReport& r);
Json to_json(const StageTimes& t);
Json to_json(const StepReport& r);

}  // namespace weft
