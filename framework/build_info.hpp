#pragma once
/// \file build_info.hpp
/// What the running binary was built from, for records that must say which code made them
/// (summary.json, checkpoint headers, benchmark meta records, `weft --version`).

namespace weft {

/// `git describe --always --dirty` of the source tree when the binary was built (a commit,
/// "-dirty" when the tree had uncommitted changes), or "unknown (...)" outside a checkout.
/// Refreshed at every build, unlike a describe at run time, which names the tree as it is
/// now rather than the code that was compiled.
const char* build_commit();

/// The project's version (CMake's PROJECT_VERSION).
const char* version();

}  // namespace weft
