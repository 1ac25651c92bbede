#include "contact/box_mesh.hpp"

namespace weft::contact {

void box_mesh(const Eigen::Vector3d& h, Eigen::MatrixX3d& V, Eigen::MatrixX3i& F) {
  V.resize(8, 3);
  for (int k = 0; k < 8; ++k)
    V.row(k) = Eigen::Vector3d((k & 1) ? h.x() : -h.x(), (k & 2) ? h.y() : -h.y(), (k & 4) ? h.z() : -h.z()).transpose();
  const int quads[6][4] = {{0, 4, 6, 2}, {1, 3, 7, 5}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 2, 3, 1}, {4, 5, 7, 6}};
  F.resize(12, 3);
  for (int q = 0; q < 6; ++q) {
    F.row(2 * q) << quads[q][0], quads[q][1], quads[q][2];
    F.row(2 * q + 1) << quads[q][0], quads[q][2], quads[q][3];
  }
}

}  // namespace weft::contact
