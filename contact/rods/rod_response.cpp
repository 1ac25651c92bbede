#include "contact/rods/rod_response.hpp"

#include <numeric>

namespace weft::contact::rods {

std::vector<std::vector<int>> contact_groups(int num_rods, const std::vector<RodContactRows>& contacts,
                                             std::vector<std::vector<int>>& group_rods, bool separate) {
  std::vector<int> parent(num_rods);
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](int a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  };
  auto unite = [&](int a, int b) {
    a = find(a), b = find(b);
    if (a != b) parent[std::max(a, b)] = std::min(a, b);  // the root is the smallest rod of the component
  };
  for (const RodContactRows& k : contacts) {
    if (k.rods[1] >= 0) unite(k.rods[0], k.rods[1]);
    if (!separate) unite(k.rods[0], contacts.front().rods[0]);  // one monolithic group
  }
  std::vector<int> slot(num_rods, -1);
  std::vector<std::vector<int>> groups;
  group_rods.clear();
  // Contacts in ascending order within a group; groups numbered by their first contact,
  // whose smallest rod is the component's root.
  for (int id = 0; id < static_cast<int>(contacts.size()); ++id) {
    const int root = find(contacts[id].rods[0]);
    if (slot[root] < 0) {
      slot[root] = static_cast<int>(groups.size());
      groups.emplace_back();
      group_rods.emplace_back();
    }
    groups[slot[root]].push_back(id);
  }
  for (int r = 0; r < num_rods; ++r) {
    const int root = find(r);
    if (slot[root] >= 0) group_rods[slot[root]].push_back(r);
  }
  return groups;
}

}  // namespace weft::contact::rods
