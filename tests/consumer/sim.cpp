// rgbdt::sim alone: the simulator's night materials keep the board warmer than the cloth.
#include <rgbdt/sim/scene.hpp>

#include <iostream>

int main() {
  using namespace rgbdt;
  const sim::MaterialPresets night = sim::material_presets(sim::TimeOfDay::kNight);
  std::cout << "consumer sim: night board " << night.white_board.temperature_k << " K, cloth "
            << night.black_cloth.temperature_k << " K\n";
  return night.white_board.temperature_k > 0 && night.black_cloth.temperature_k > 0 ? 0 : 1;
}
