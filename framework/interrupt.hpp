#pragma once
/// \file interrupt.hpp
/// A request to stop, made asynchronously (by `weft run`'s SIGINT/SIGTERM handler, or by
/// another thread of a host application) and honoured by the long loops of a step: every
/// Newton iteration and every iteration of the rod contact solvers polls it and returns
/// `Status::interrupted`. The step then fails as any failed step does: its state is the
/// state at its start, so the caller can checkpoint it and resume later.
#include <atomic>

namespace weft {

namespace detail {
inline std::atomic<int> stop_signal{0};
static_assert(std::atomic<int>::is_always_lock_free, "set from a signal handler");
}  // namespace detail

/// Ask the running step to stop; `code` (nonzero, e.g. the signal number) is kept for the
/// caller. Async-signal-safe.
inline void request_stop(int code) noexcept { detail::stop_signal.store(code, std::memory_order_relaxed); }
/// Withdraw the request (before a new run).
inline void clear_stop() noexcept { detail::stop_signal.store(0, std::memory_order_relaxed); }
/// The pending request's code; 0: none.
inline int stop_requested() noexcept { return detail::stop_signal.load(std::memory_order_relaxed); }

}  // namespace weft
