#include "framework/obj_io.hpp"

#include <tiny_obj_loader.h>

#include <cstdio>
#include <filesystem>
#include <fstream>

#include "framework/error.hpp"
#include "framework/writers.hpp"

namespace weft {

MeshData read_obj(const std::string& path) {
  if (!std::filesystem::is_regular_file(path)) throw ConfigError(fmt::format("{}: mesh file not found", path));
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

void write_obj(const std::string& path, const Eigen::VectorXd& x, const Eigen::MatrixX3i& F, const std::string& comment) {
  AtomicFile out(path);
  auto& s = out.stream();
  if (!comment.empty()) s << "# " << comment << "\n";
  for (Eigen::Index i = 0; i < x.size() / 3; ++i) s << fmt::format("v {} {} {}\n", x[3 * i], x[3 * i + 1], x[3 * i + 2]);
  for (Eigen::Index f = 0; f < F.rows(); ++f) s << fmt::format("f {} {} {}\n", F(f, 0) + 1, F(f, 1) + 1, F(f, 2) + 1);
  out.commit();
}

}  // namespace weft
