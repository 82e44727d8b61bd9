// rgbdt::cloud alone: a cloud written as binary_compressed PCD and read back checked.
#include <rgbdt/cloud/pcd_io.hpp>

#include <cstdio>
#include <iostream>
#include <string>

int main() {
  using namespace rgbdt;
  cloud::Cloud c;
  for (int k = 0; k < 100; ++k) {
    cloud::PointXYZIRT p;
    p.x = 0.1f * k;
    p.y = 1.0f;
    p.z = -0.5f;
    c.push_back(p);
  }
  const std::string path = "consumer_cloud.pcd";
  cloud::save_pcd(path, c, cloud::PcdFormat::kBinaryCompressed);
  const cloud::LoadedCloud loaded = cloud::load_pcd(path);
  std::remove(path.c_str());
  std::cout << "consumer cloud: " << loaded.cloud->size() << " points read back\n";
  return loaded.cloud->size() == c.size() && loaded.cloud->points[99].x == c.points[99].x ? 0 : 1;
}
