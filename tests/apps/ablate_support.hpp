#pragma once
// Shared by the ablation tests of cloth (test_ablate.cpp) and rods (test_ablate_rods.cpp).
#include <doctest/doctest.h>

#include <string>
#include <vector>

#include "apps/ablate.hpp"

namespace weft::test {

/// `weft ablate` of one combination against itself as the reference (no substeps, no
/// tightening): the single CSV row, whose error must be zero.
inline app::AblateRow self_reference(app::AblateOptions o, const std::string& combo) {
  o.combos = {combo};
  o.reference = combo;
  o.reference_substeps = 1;
  o.reference_tighten = false;
  std::vector<app::AblateRow> rows;
  REQUIRE(app::run_ablate(o, &rows) == 0);
  REQUIRE(rows.size() == 1);
  return rows[0];
}

}  // namespace weft::test
