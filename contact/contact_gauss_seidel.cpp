#include "contact/contact_gauss_seidel.hpp"

namespace weft::contact {

// The two operators provided, compiled once (contact_gauss_seidel.hpp declares them extern).
template GaussSeidelReport gauss_seidel<DenseDelassus>(DenseDelassus&, std::span<const double>, std::vector<Eigen::Vector3d>&,
                                                       const GaussSeidelParams&);
template GaussSeidelReport gauss_seidel<ComplianceDelassus>(ComplianceDelassus&, std::span<const double>,
                                                            std::vector<Eigen::Vector3d>&, const GaussSeidelParams&);

}  // namespace weft::contact
