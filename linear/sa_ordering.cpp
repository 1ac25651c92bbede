/// \file sa_ordering.cpp
/// `sa::order_aggregates`: the aggregates renumbered by reverse Cuthill-McKee (Boost.Graph),
/// in a translation unit of its own so the graph headers stay out of the other stages.
#include <algorithm>
#include <cstdlib>
#include <utility>
#include <vector>

#include <boost/graph/adjacency_list.hpp>
#include <boost/graph/cuthill_mckee_ordering.hpp>

#include "linear/sa_amg.hpp"

namespace weft::linear::sa {

template <int B>
std::vector<int> order_aggregates(const BsrView<B, B>& A, Aggregates& aggs, AggregateOrder mode) {
  const int count = aggs.count;
  if (count < 3 || mode == AggregateOrder::natural) return {};
  const std::vector<int>& agg = aggs.node_agg;
  std::vector<std::pair<int, int>> edges;
  for (int i = 0; i < A.rows; ++i) {
    const int a = agg[i];
    if (a < 0) continue;
    for (int k = A.row_ptr[i]; k < A.row_ptr[i + 1]; ++k) {
      const int b = agg[A.col[k]];
      if (b > a) edges.emplace_back(a, b);
    }
  }
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());

  using Graph = boost::adjacency_list<boost::vecS, boost::vecS, boost::undirectedS,
                                      boost::property<boost::vertex_color_t, boost::default_color_type,
                                                      boost::property<boost::vertex_degree_t, int>>>;
  Graph g(count);
  for (const auto& [a, b] : edges) boost::add_edge(a, b, g);
  std::vector<Graph::vertex_descriptor> order(count);  // order[new] = old, reversed (RCM)
  // Every component from a pseudo-peripheral node of smallest degree, in vertex order.
  boost::cuthill_mckee_ordering(g, order.rbegin(), boost::get(boost::vertex_color, g), boost::make_degree_map(g));
  std::vector<int> label(count);
  for (int t = 0; t < count; ++t) label[order[t]] = t;
  if (mode == AggregateOrder::automatic) {
    double natural = 0, reordered = 0;
    for (const auto& [a, b] : edges) natural += b - a, reordered += std::abs(label[a] - label[b]);
    if (!(reordered < 0.5 * natural)) return {};
  }
  for (int& a : aggs.node_agg)
    if (a >= 0) a = label[a];
  return label;
}

template std::vector<int> order_aggregates<3>(const BsrView<3, 3>&, Aggregates&, AggregateOrder);
template std::vector<int> order_aggregates<6>(const BsrView<6, 6>&, Aggregates&, AggregateOrder);

}  // namespace weft::linear::sa
