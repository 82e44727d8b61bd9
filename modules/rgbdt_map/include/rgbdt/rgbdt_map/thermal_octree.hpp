#pragma once
/// \file
/// An OctoMap occupancy octree whose nodes carry a temperature, for planners that want to
/// reason about heat (people, engines, sun-warmed pavement). It is registered with
/// octomap::AbstractOcTree's tree-type registry under "ThermalOcTree", so
/// octomap::AbstractOcTree::read("map_thermal.ot") returns a ThermalOcTree once this
/// library is loaded. Inner nodes hold the mean temperature of their children.
#include <octomap/OcTreeNode.h>
#include <octomap/OccupancyOcTreeBase.h>

#include <cmath>
#include <iosfwd>
#include <limits>
#include <string>

namespace rgbdt::rgbdt_map {

class ThermalOcTree;

class ThermalOcTreeNode : public octomap::OcTreeNode {
 public:
  friend class ThermalOcTree;
  ThermalOcTreeNode() = default;
  ThermalOcTreeNode(const ThermalOcTreeNode& rhs) : OcTreeNode(rhs), temperature_k_(rhs.temperature_k_) {}

  bool operator==(const ThermalOcTreeNode& rhs) const {
    return rhs.value == value && (rhs.temperature_k_ == temperature_k_ ||
                                  (std::isnan(rhs.temperature_k_) && std::isnan(temperature_k_)));
  }
  void copyData(const ThermalOcTreeNode& from) {
    OcTreeNode::copyData(from);
    temperature_k_ = from.temperature_k_;
  }

  float temperature_k() const { return temperature_k_; }  ///< [K]; NaN when unknown
  void set_temperature_k(float kelvin) { temperature_k_ = kelvin; }
  bool has_temperature() const { return !std::isnan(temperature_k_); }
  /// Mean temperature of the children that have one (NaN if none).
  float mean_child_temperature_k() const;

  std::istream& readData(std::istream& s);
  std::ostream& writeData(std::ostream& s) const;

 protected:
  float temperature_k_ = std::numeric_limits<float>::quiet_NaN();
};

class ThermalOcTree : public octomap::OccupancyOcTreeBase<ThermalOcTreeNode> {
 public:
  explicit ThermalOcTree(double resolution_m);
  ThermalOcTree* create() const override { return new ThermalOcTree(resolution); }
  std::string getTreeType() const override { return "ThermalOcTree"; }

  /// Siblings collapse only when both occupancy and temperature agree, so pruning never
  /// loses temperatures.
  bool pruneNode(ThermalOcTreeNode* node) override;
  bool isNodeCollapsible(const ThermalOcTreeNode* node) const override;

  /// Sets the temperature of an existing node; returns it, or nullptr if there is none.
  ThermalOcTreeNode* set_node_temperature(const octomap::OcTreeKey& key, float kelvin);
  /// Occupancy and temperature of inner nodes from their children (call before writing).
  void update_inner_nodes();

 protected:
  void update_inner_recurs(ThermalOcTreeNode* node, unsigned int depth);

  /// Registers the tree type with AbstractOcTree (as octomap's own trees do) so that
  /// AbstractOcTree::read can create ThermalOcTrees.
  class StaticMemberInitializer {
   public:
    StaticMemberInitializer();
    void ensureLinking() {}
  };
  static StaticMemberInitializer thermal_octree_member_init_;
};

}  // namespace rgbdt::rgbdt_map
