#pragma once
/// \file writers.hpp
/// Output that survives failures: every file is written to a temporary name and renamed
/// when complete; the .pvd series is rewritten after each frame, so it always lists
/// exactly the frames on disk; statistics are JSON lines flushed one step at a time.
#include <Eigen/Core>

#include <cstdint>
#include <fstream>
#include <string>
#include <vector>

#include "framework/params_json.hpp"

namespace weft {

/// A file that appears under its name only when `commit` is called.
class AtomicFile {
 public:
  explicit AtomicFile(std::string path);
  ~AtomicFile();  // removes the temporary file if not committed
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;
  std::ofstream& stream() { return out_; }
  void commit();  ///< flush, close and rename; throws std::runtime_error on I/O failure

 private:
  std::string path_, tmp_;
  std::ofstream out_;
  bool committed_ = false;
};

/// Write a JSON document atomically (pretty-printed).
void write_json_file(const std::string& path, const Json& j);

/// VTK XML PolyData (.vtp, ASCII): triangles plus per-point velocity.
void write_vtp(const std::string& path, const Eigen::VectorXd& x, const Eigen::MatrixX3i& F,
               const Eigen::VectorXd* velocity = nullptr);

/// Rods as polylines: vertices x (stacked), rod r = vertices first[r] .. first[r+1]-1.
/// OBJ with `l` elements, and VTK PolyData with Lines (velocity as point data if given).
void write_polylines_obj(const std::string& path, const Eigen::VectorXd& x, const std::vector<int>& first, const std::string& comment = {});
void write_polylines_vtp(const std::string& path, const Eigen::VectorXd& x, const std::vector<int>& first,
                         const Eigen::VectorXd* velocity = nullptr);

/// A ParaView collection (.pvd) listing time-stamped datasets.
class PvdSeries {
 public:
  explicit PvdSeries(std::string path) : path_(std::move(path)) {}
  /// Add a dataset (file name relative to the .pvd) and rewrite the .pvd.
  void add(double time, const std::string& file, int part = 0);
  const std::string& path() const { return path_; }

 private:
  struct Entry { double time; int part; std::string file; };
  std::string path_;
  std::vector<Entry> entries_;
};

/// Per-step statistics, one JSON object per line, flushed after every line. A line that
/// cannot be written whole (a full disk) is cut off the file again, so that the file ends
/// with the last complete line, and std::runtime_error says why.
class StatsWriter {
 public:
  explicit StatsWriter(const std::string& path);
  void write(const Json& line);
  /// A line already serialised (e.g. kept from an earlier run on resume).
  void write_line(const std::string& line);

 private:
  std::string path_;
  std::ofstream out_;
  std::uintmax_t complete_ = 0;  ///< bytes of complete lines written
};

}  // namespace weft
