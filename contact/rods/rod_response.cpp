#include "contact/rods/rod_response.hpp"

#include "framework/union_find.hpp"

namespace weft::contact::rods {

std::vector<std::vector<int>> contact_groups(int num_rods, const std::vector<RodContactRows>& contacts,
                                             std::vector<std::vector<int>>& group_rods, bool separate) {
  UnionFind uf(num_rods);  // the root is the smallest rod of the component
  for (const RodContactRows& k : contacts) {
    if (k.rods[1] >= 0) uf.unite(k.rods[0], k.rods[1]);
    if (!separate) uf.unite(k.rods[0], contacts.front().rods[0]);  // one monolithic group
  }
  std::vector<int> slot(num_rods, -1);
  std::vector<std::vector<int>> groups;
  group_rods.clear();
  // Contacts in ascending order within a group; groups numbered by their first contact,
  // whose smallest rod is the component's root.
  for (int id = 0; id < static_cast<int>(contacts.size()); ++id) {
    const int root = uf.find(contacts[id].rods[0]);
    if (slot[root] < 0) {
      slot[root] = static_cast<int>(groups.size());
      groups.emplace_back();
      group_rods.emplace_back();
    }
    groups[slot[root]].push_back(id);
  }
  for (int r = 0; r < num_rods; ++r) {
    const int root = uf.find(r);
    if (slot[root] >= 0) group_rods[slot[root]].push_back(r);
  }
  return groups;
}

}  // namespace weft::contact::rods
