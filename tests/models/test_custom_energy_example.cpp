// The custom energy of examples/custom_energy (edge springs, the teaching tour's example) is
// held to the library's own standard: gradient and Hessian against finite differences, on
// a random configuration and on compressed and inverted ones, exact and projected.
#include <doctest/doctest.h>

#include <Eigen/Eigenvalues>

#include "examples/custom_energy/edge_springs.hpp"
#include "tests/support/fd.hpp"

using namespace weft;

TEST_SUITE("models") {
  TEST_CASE("custom energy example: edge springs have exact derivatives") {
    Json doc = Json::parse(R"({"combo": "cloth_ip_direct", "cloths": [{"mesh": {"source": "rectangle", "size": [0.1, 0.1], "resolution": [4, 4]}}],
                              "time": {"dt": 0.01, "duration": 0.1, "frame_rate": 100}})");
    const Scene scene = build_scene(doc, ".", "test");
    EdgeSprings springs(scene, EdgeSprings::Params{.stiffness = 50});
    const double h = support::fd_step(scene.mesh);
    std::srand(3);
    for (const double amplitude : {0.003, 0.03, 0.3}) {  // gentle, compressed edges, inverted triangles
      CAPTURE(amplitude);
      State s = scene.initial_state();
      s.x += amplitude * 0.1 * Eigen::VectorXd::Random(s.x.size());
      const Eigen::VectorXd g = support::gradient(springs, s), g_fd = support::fd_gradient(springs, s, h);
      CHECK(g.norm() > 1e-3);  // not a vacuous comparison
      CHECK(support::spec_error(g_fd, g) < 1e-6);
      const Eigen::MatrixXd H = support::dense_hessian(springs, s, HessianMode::exact), H_fd = support::fd_hessian(springs, s, h);
      CHECK(support::spec_error(H_fd, H) < 1e-6);
      const Eigen::MatrixXd P = support::dense_hessian(springs, s, HessianMode::projected);
      CHECK(Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(P).eigenvalues().minCoeff() > -1e-9 * P.norm());
      if (amplitude >= 0.03) CHECK((P - H).norm() > 1e-6 * H.norm());  // some edge is compressed: the projection acts
    }
  }
}
