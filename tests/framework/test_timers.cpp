// Stage timers are exclusive: a stage nested in another is charged once, so the stages of a
// step add up to at most its wall time (the bench's shares rely on it).
#include <doctest/doctest.h>

#include <cmath>
#include <thread>

#include "framework/timers.hpp"

using namespace weft;
using namespace std::chrono_literals;

TEST_CASE("timers: a stage nested in another is taken out of the enclosing stage") {
  StageTimes times;
  double plain = 0;
  const auto t0 = std::chrono::steady_clock::now();
  {
    ScopedTimer outer(times, Stage::line_search);
    ScopedTimer inclusive(plain);  // plain accumulators see the whole scope
    std::this_thread::sleep_for(20ms);
    {
      ScopedTimer inner(times, Stage::energy);
      std::this_thread::sleep_for(40ms);
      {
        ScopedTimer innermost(times, Stage::hessian);
        std::this_thread::sleep_for(20ms);
      }
    }
  }
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  CAPTURE(wall);
  CHECK(times.total() <= wall);
  CHECK(times[Stage::hessian] >= 0.020);
  CHECK(times[Stage::energy] >= 0.040);
  CHECK(times[Stage::line_search] >= 0.020);
  CHECK(times[Stage::line_search] < wall - 0.060 + 1e-9);
  CHECK(plain >= 0.080);
  // The exclusive stages add up to the outermost scope, not to 20 + 60 + 80 ms.
  CHECK(std::abs(times.total() - plain) < 1e-3);
  // After the scopes close a new stage timer has no parent.
  { ScopedTimer again(times, Stage::output); }
  CHECK(times[Stage::line_search] < wall - 0.060 + 1e-9);
}
