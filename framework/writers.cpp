#include "framework/writers.hpp"

#include <fmt/format.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <stdexcept>

namespace weft {

namespace {
std::string os_reason() { return errno ? std::strerror(errno) : "I/O error"; }
}  // namespace

AtomicFile::AtomicFile(std::string path) : path_(std::move(path)), tmp_(path_ + ".tmp") {
  errno = 0;
  out_.open(tmp_, std::ios::out | std::ios::trunc);
  if (!out_) throw std::runtime_error(fmt::format("cannot write {}: {}", tmp_, os_reason()));
  out_.precision(17);
}

AtomicFile::~AtomicFile() {
  if (!committed_) {
    out_.close();
    std::error_code ec;
    std::filesystem::remove(tmp_, ec);
  }
}

void AtomicFile::commit() {
  errno = 0;
  out_.flush();
  const bool ok = static_cast<bool>(out_);
  const std::string why = os_reason();
  out_.close();
  if (!ok || !out_) throw std::runtime_error(fmt::format("error while writing {}: {}", tmp_, ok ? os_reason() : why));
  std::error_code ec;
  std::filesystem::rename(tmp_, path_, ec);
  if (ec) throw std::runtime_error(fmt::format("cannot rename {} to {}: {}", tmp_, path_, ec.message()));
  committed_ = true;
}

void write_json_file(const std::string& path, const Json& j) {
  AtomicFile f(path);
  f.stream() << j.dump(2) << "\n";
  f.commit();
}

namespace {
/// The VTK PolyData header of a piece, its points and their velocity (if any).
void vtp_points(std::ostream& s, const Eigen::VectorXd& x, const Eigen::VectorXd* velocity, Eigen::Index lines, Eigen::Index polys) {
  const Eigen::Index nv = x.size() / 3;
  s << "<?xml version=\"1.0\"?>\n"
       "<VTKFile type=\"PolyData\" version=\"0.1\" byte_order=\"LittleEndian\">\n<PolyData>\n";
  s << fmt::format("<Piece NumberOfPoints=\"{}\" NumberOfVerts=\"0\" NumberOfLines=\"{}\" NumberOfStrips=\"0\" NumberOfPolys=\"{}\">\n", nv, lines, polys);
  s << "<Points>\n<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">\n";
  for (Eigen::Index i = 0; i < nv; ++i) s << fmt::format("{} {} {}\n", x[3 * i], x[3 * i + 1], x[3 * i + 2]);
  s << "</DataArray>\n</Points>\n";
  if (velocity) {
    s << "<PointData Vectors=\"velocity\">\n<DataArray type=\"Float64\" Name=\"velocity\" NumberOfComponents=\"3\" format=\"ascii\">\n";
    for (Eigen::Index i = 0; i < nv; ++i) s << fmt::format("{} {} {}\n", (*velocity)[3 * i], (*velocity)[3 * i + 1], (*velocity)[3 * i + 2]);
    s << "</DataArray>\n</PointData>\n";
  }
}
}  // namespace

void write_vtp(const std::string& path, const Eigen::VectorXd& x, const Eigen::MatrixX3i& F, const Eigen::VectorXd* velocity) {
  AtomicFile f(path);
  auto& s = f.stream();
  const Eigen::Index nf = F.rows();
  vtp_points(s, x, velocity, 0, nf);
  s << "<Polys>\n<DataArray type=\"Int32\" Name=\"connectivity\" format=\"ascii\">\n";
  for (Eigen::Index k = 0; k < nf; ++k) s << fmt::format("{} {} {}\n", F(k, 0), F(k, 1), F(k, 2));
  s << "</DataArray>\n<DataArray type=\"Int32\" Name=\"offsets\" format=\"ascii\">\n";
  for (Eigen::Index k = 0; k < nf; ++k) s << 3 * (k + 1) << (k % 16 == 15 ? "\n" : " ");
  s << "\n</DataArray>\n</Polys>\n</Piece>\n</PolyData>\n</VTKFile>\n";
  f.commit();
}

void write_polylines_obj(const std::string& path, const Eigen::VectorXd& x, const std::vector<int>& first, const std::string& comment) {
  AtomicFile f(path);
  auto& s = f.stream();
  if (!comment.empty()) s << "# " << comment << "\n";
  for (Eigen::Index i = 0; i < x.size() / 3; ++i) s << fmt::format("v {} {} {}\n", x[3 * i], x[3 * i + 1], x[3 * i + 2]);
  for (size_t r = 0; r + 1 < first.size(); ++r) {
    s << "l";
    for (int i = first[r]; i < first[r + 1]; ++i) s << ' ' << i + 1;
    s << "\n";
  }
  f.commit();
}

void write_polylines_vtp(const std::string& path, const Eigen::VectorXd& x, const std::vector<int>& first, const Eigen::VectorXd* velocity) {
  AtomicFile f(path);
  auto& s = f.stream();
  const Eigen::Index nv = x.size() / 3;
  const size_t nl = first.empty() ? 0 : first.size() - 1;
  vtp_points(s, x, velocity, static_cast<Eigen::Index>(nl), 0);
  s << "<Lines>\n<DataArray type=\"Int32\" Name=\"connectivity\" format=\"ascii\">\n";
  for (Eigen::Index i = 0; i < nv; ++i) s << i << (i % 16 == 15 ? "\n" : " ");
  s << "\n</DataArray>\n<DataArray type=\"Int32\" Name=\"offsets\" format=\"ascii\">\n";
  for (size_t r = 0; r < nl; ++r) s << first[r + 1] << (r % 16 == 15 ? "\n" : " ");
  s << "\n</DataArray>\n</Lines>\n</Piece>\n</PolyData>\n</VTKFile>\n";
  f.commit();
}

void PvdSeries::add(double time, const std::string& file, int part) {
  entries_.push_back({time, part, file});
  AtomicFile f(path_);
  auto& s = f.stream();
  s << "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n<Collection>\n";
  for (const auto& e : entries_)
    s << fmt::format("  <DataSet timestep=\"{}\" group=\"\" part=\"{}\" file=\"{}\"/>\n", e.time, e.part, e.file);
  s << "</Collection>\n</VTKFile>\n";
  f.commit();
}

StatsWriter::StatsWriter(const std::string& path) : path_(path) {
  errno = 0;
  out_.open(path, std::ios::out | std::ios::trunc);
  if (!out_) throw std::runtime_error(fmt::format("cannot write {}: {}", path, os_reason()));
}

void StatsWriter::write(const Json& line) { write_line(line.dump()); }

void StatsWriter::write_line(const std::string& line) {
  if (!out_.is_open()) throw std::runtime_error(fmt::format("{} was closed by an earlier write error", path_));
  errno = 0;
  out_ << line << '\n';
  out_.flush();
  if (out_) {
    complete_ += line.size() + 1;
    return;
  }
  const std::string why = os_reason();
  out_.close();
  std::error_code ec;
  std::filesystem::resize_file(path_, complete_, ec);  // keep only the complete lines
  throw std::runtime_error(fmt::format("error while writing {}: {}", path_, why));
}

}  // namespace weft
