#pragma once
/// \file files.hpp
/// The check every input file goes through before it is opened: it exists and is a regular
/// file (a directory or a FIFO given as a scene, mesh or checkpoint is named as such; a FIFO
/// would block the reader).
#include <filesystem>
#include <string>
#include <string_view>

#include "framework/error.hpp"

namespace weft {

/// Throws ConfigError "PATH: KIND not found" or "PATH: not a regular file (a directory); give
/// GIVE" unless `path` names a regular file.
inline void require_regular_file(const std::string& path, std::string_view kind, std::string_view give) {
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  if (ec || !std::filesystem::exists(status)) throw ConfigError(fmt::format("{}: {} not found", path, kind));
  if (!std::filesystem::is_regular_file(status))
    throw ConfigError(fmt::format("{}: not a regular file (a {}); give {}", path,
                                  std::filesystem::is_directory(status) ? "directory" : "FIFO, socket or device", give));
}

}  // namespace weft
