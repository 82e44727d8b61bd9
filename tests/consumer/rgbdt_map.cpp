// rgbdt::rgbdt_map alone: two points in one 5 cm voxel, one in another.
#include <rgbdt/rgbdt_map/voxel_map.hpp>

#include <iostream>

int main() {
  using namespace rgbdt;
  rgbdt_map::VoxelMap map;
  map.insert({{0.01f, 0.01f, 0.01f}, {0.02f, 0.02f, 0.02f}, {1.0f, 1.0f, 1.0f}}, nullptr, nullptr,
             0, 0.0);
  std::cout << "consumer rgbdt_map: " << map.size() << " voxels\n";
  return map.size() == 2 ? 0 : 1;
}
