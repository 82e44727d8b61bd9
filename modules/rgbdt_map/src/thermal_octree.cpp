#include "rgbdt/rgbdt_map/thermal_octree.hpp"

#include <istream>
#include <ostream>

namespace rgbdt::rgbdt_map {

float ThermalOcTreeNode::mean_child_temperature_k() const {
  double sum = 0.0;
  int count = 0;
  if (children != nullptr) {
    for (int i = 0; i < 8; ++i) {
      const auto* child = static_cast<const ThermalOcTreeNode*>(children[i]);
      if (child != nullptr && child->has_temperature()) {
        sum += child->temperature_k_;
        ++count;
      }
    }
  }
  return count > 0 ? static_cast<float>(sum / count) : std::numeric_limits<float>::quiet_NaN();
}

std::istream& ThermalOcTreeNode::readData(std::istream& s) {
  s.read(reinterpret_cast<char*>(&value), sizeof(value));
  s.read(reinterpret_cast<char*>(&temperature_k_), sizeof(temperature_k_));
  return s;
}

std::ostream& ThermalOcTreeNode::writeData(std::ostream& s) const {
  s.write(reinterpret_cast<const char*>(&value), sizeof(value));
  s.write(reinterpret_cast<const char*>(&temperature_k_), sizeof(temperature_k_));
  return s;
}

ThermalOcTree::StaticMemberInitializer::StaticMemberInitializer() {
  auto* tree = new ThermalOcTree(0.1);  // owned by octomap's registry for the program's life
  tree->clearKeyRays();
  octomap::AbstractOcTree::registerTreeType(tree);
}

ThermalOcTree::StaticMemberInitializer ThermalOcTree::thermal_octree_member_init_;

ThermalOcTree::ThermalOcTree(double resolution_m) : OccupancyOcTreeBase<ThermalOcTreeNode>(resolution_m) {
  thermal_octree_member_init_.ensureLinking();
}

bool ThermalOcTree::isNodeCollapsible(const ThermalOcTreeNode* node) const {
  if (!nodeChildExists(node, 0)) return false;
  const ThermalOcTreeNode* first = getNodeChild(node, 0);
  if (nodeHasChildren(first)) return false;
  for (unsigned int i = 1; i < 8; ++i) {
    if (!nodeChildExists(node, i)) return false;
    const ThermalOcTreeNode* child = getNodeChild(node, i);
    if (nodeHasChildren(child) || !(*child == *first)) return false;
  }
  return true;
}

bool ThermalOcTree::pruneNode(ThermalOcTreeNode* node) {
  if (!isNodeCollapsible(node)) return false;
  node->copyData(*getNodeChild(node, 0));
  for (unsigned int i = 0; i < 8; ++i) deleteNodeChild(node, i);
  delete[] node->children;
  node->children = nullptr;
  return true;
}

ThermalOcTreeNode* ThermalOcTree::set_node_temperature(const octomap::OcTreeKey& key, float kelvin) {
  ThermalOcTreeNode* node = search(key);
  if (node != nullptr) node->set_temperature_k(kelvin);
  return node;
}

void ThermalOcTree::update_inner_nodes() {
  if (root != nullptr) update_inner_recurs(root, 0);
}

void ThermalOcTree::update_inner_recurs(ThermalOcTreeNode* node, unsigned int depth) {
  if (!nodeHasChildren(node)) return;
  if (depth < tree_depth) {
    for (unsigned int i = 0; i < 8; ++i) {
      if (nodeChildExists(node, i)) update_inner_recurs(getNodeChild(node, i), depth + 1);
    }
  }
  node->updateOccupancyChildren();
  node->set_temperature_k(node->mean_child_temperature_k());
}

}  // namespace rgbdt::rgbdt_map
