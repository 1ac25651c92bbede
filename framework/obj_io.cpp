#include "framework/obj_io.hpp"

#include <tiny_obj_loader.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "framework/error.hpp"
#include "framework/files.hpp"
#include "framework/writers.hpp"

namespace weft {

namespace {

/// The OBJ statements weft reads, checked line by line before tinyobjloader parses the
/// file, so that an error names its line: `v` with three finite coordinates, `vt`, and `f`
/// whose indices (1-based, or negative: relative to the end, `v/vt/vn` forms) exist.
void check_obj_lines(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw ConfigError(fmt::format("{}: mesh file not readable", path));
  long long nv = 0, nt = 0, line_no = 0;
  std::string line;
  const auto bad = [&](const std::string& what) {
    return ConfigError(fmt::format("{}:{}: malformed OBJ: {} (line: \"{}\")", path, line_no, what, line.size() > 80 ? line.substr(0, 80) + "..." : line));
  };
  while (std::getline(in, line)) {
    ++line_no;
    std::istringstream ss(line);
    std::string tag;
    if (!(ss >> tag) || tag[0] == '#') continue;
    if (tag == "v") {
      std::string word;
      for (int c = 0; c < 3; ++c) {
        if (!(ss >> word)) throw bad("a vertex needs three coordinates");
        char* end = nullptr;
        const double x = std::strtod(word.c_str(), &end);
        if (end == word.c_str() || *end != '\0') throw bad(fmt::format("coordinate '{}' is not a number", word));
        if (!std::isfinite(x)) throw bad(fmt::format("coordinate '{}' is not finite (valid: |x| < 1.8e308)", word));
      }
      ++nv;
    } else if (tag == "vt") {
      ++nt;
    } else if (tag == "f") {
      std::string word;
      int corners = 0;
      while (ss >> word) {
        ++corners;
        for (int part = 0; part < 2; ++part) {  // the vertex and the texture index of v/vt/vn
          const size_t slash = word.find('/');
          const std::string token = part == 0 ? word.substr(0, slash) : (slash == std::string::npos ? "" : word.substr(slash + 1, word.find('/', slash + 1) - slash - 1));
          if (part == 1 && token.empty()) break;
          char* end = nullptr;
          errno = 0;
          const long long i = std::strtoll(token.c_str(), &end, 10);
          const long long n = part == 0 ? nv : nt;
          const char* what = part == 0 ? "vertex" : "texture coordinate";
          if (token.empty() || end == token.c_str() || *end != '\0' || errno == ERANGE)
            throw bad(fmt::format("face corner '{}' is not an index", word));
          if (i == 0 || i > n || i < -n)
            throw bad(fmt::format("face corner '{}' references {} {} of the {} defined before this line (valid: 1..{} or -1..-{})", word, what, i,
                                  n, n, n));
        }
      }
      if (corners < 3) throw bad(fmt::format("a face needs at least three corners, this one has {}", corners));
    }
  }
}

}  // namespace

MeshData read_obj(const std::string& path) {
  require_regular_file(path, "mesh file", "an OBJ file");
  check_obj_lines(path);
  tinyobj::ObjReaderConfig config;
  config.triangulate = true;
  config.vertex_color = false;
  config.mtl_search_path = "";
  tinyobj::ObjReader reader;
  if (!reader.ParseFromFile(path, config))
    throw ConfigError(fmt::format("{}: malformed OBJ: {}", path, reader.Error().empty() ? "parse error" : reader.Error()));
  const auto& attrib = reader.GetAttrib();
  MeshData m;
  const auto nv = static_cast<Eigen::Index>(attrib.vertices.size() / 3);
  m.V.resize(nv, 3);
  for (Eigen::Index i = 0; i < nv; ++i)
    for (int c = 0; c < 3; ++c) m.V(i, c) = attrib.vertices[3 * i + c];
  std::vector<Eigen::Vector3i> faces, face_uvs;
  for (const auto& shape : reader.GetShapes()) {
    size_t offset = 0;
    for (size_t f = 0; f < shape.mesh.num_face_vertices.size(); ++f) {
      const int n = shape.mesh.num_face_vertices[f];
      if (n == 3) {
        const auto& idx = shape.mesh.indices;
        faces.emplace_back(idx[offset].vertex_index, idx[offset + 1].vertex_index, idx[offset + 2].vertex_index);
        face_uvs.emplace_back(idx[offset].texcoord_index, idx[offset + 1].texcoord_index, idx[offset + 2].texcoord_index);
      }
      offset += n;
    }
  }
  if (faces.empty()) throw ConfigError(fmt::format("{}: malformed OBJ: no triangle faces", path));
  for (const auto& f : faces)
    for (int c = 0; c < 3; ++c)
      if (f[c] < 0 || f[c] >= nv)
        throw ConfigError(fmt::format("{}: malformed OBJ: face references vertex {} of {}", path, f[c] + 1, nv));
  m.F.resize(static_cast<Eigen::Index>(faces.size()), 3);
  for (size_t k = 0; k < faces.size(); ++k) m.F.row(static_cast<Eigen::Index>(k)) = faces[k].transpose();
  // Texture coordinates (`vt u v [w]`, tinyobjloader keeps u and v): per face corner, as
  // OBJ indexes them separately from the vertices (seams). Corners without one keep -1.
  const auto nt = static_cast<Eigen::Index>(attrib.texcoords.size() / 2);
  if (nt > 0) {
    m.UV.resize(nt, 2);
    for (Eigen::Index i = 0; i < nt; ++i)
      for (int c = 0; c < 2; ++c) m.UV(i, c) = attrib.texcoords[2 * i + c];
    m.FUV.resize(m.F.rows(), 3);
    for (size_t k = 0; k < face_uvs.size(); ++k)
      for (int c = 0; c < 3; ++c) {
        const int t = face_uvs[k][c];
        if (t >= nt) throw ConfigError(fmt::format("{}: malformed OBJ: face references texture coordinate {} of {}", path, t + 1, nt));
        m.FUV(static_cast<Eigen::Index>(k), c) = t < 0 ? -1 : t;
      }
  }
  return m;
}

std::string check_extent(const Eigen::MatrixX3d& V) {
  for (Eigen::Index i = 0; i < V.rows(); ++i)
    for (int c = 0; c < 3; ++c)
      if (!(std::abs(V(i, c)) <= max_coordinate))
        return fmt::format("vertex {} has the coordinate {} = {} m; valid: finite and within {:.0e} m of the origin (meters are the unit)", i,
                           "xyz"[c], V(i, c), max_coordinate);
  return {};
}

void write_obj(const std::string& path, const Eigen::VectorXd& x, const Eigen::MatrixX3i& F, const std::string& comment) {
  AtomicFile out(path);
  auto& s = out.stream();
  if (!comment.empty()) s << "# " << comment << "\n";
  for (Eigen::Index i = 0; i < x.size() / 3; ++i) s << fmt::format("v {} {} {}\n", x[3 * i], x[3 * i + 1], x[3 * i + 2]);
  for (Eigen::Index f = 0; f < F.rows(); ++f) s << fmt::format("f {} {} {}\n", F(f, 0) + 1, F(f, 1) + 1, F(f, 2) + 1);
  out.commit();
}

}  // namespace weft
