#pragma once
// The body of the cloud-reader fuzz target, shared by the libFuzzer program and by the gtest
// that replays the regression corpus. The bytes go to a file (the readers take a path) and
// through load_pcd, load_ply and load_cloud; a refusal must be rgbdt::core::Error naming
// the file, and an accepted cloud must satisfy the readers' promises. Anything else aborts.
#include <unistd.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "rgbdt/cloud/cloud_io.hpp"
#include "rgbdt/core/error.hpp"

namespace rgbdt::cloud::fuzz {

/// Number of readers (of load_pcd, load_ply) that accepted the bytes.
inline int cloud_input(const std::uint8_t* data, std::size_t size) {
  const bool ply = size >= 3 && data[0] == 'p' && data[1] == 'l' && data[2] == 'y';
  const std::string path = (std::getenv("TMPDIR") ? std::string(std::getenv("TMPDIR")) : "/tmp") +
                           "/rgbdt_cloud_fuzz_" + std::to_string(::getpid()) +
                           (ply ? ".ply" : ".pcd");
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) std::abort();
  if (size && std::fwrite(data, 1, size, f) != size) std::abort();
  if (std::fclose(f) != 0) std::abort();

  int accepted = 0;
  const auto check = [&](LoadedCloud (*load)(const std::string&)) {
    try {
      const LoadedCloud out = load(path);
      ++accepted;
      if (!out.cloud || out.cloud->size() != out.cloud->width) std::abort();
      for (const auto& p : *out.cloud) {
        if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) std::abort();
        if (!std::isfinite(p.intensity) || !(std::abs(p.t) <= 3600.0f) || p.ring > 1023) {
          std::abort();
        }
      }
    } catch (const rgbdt::core::Error& e) {
      if (std::string(e.what()).find(path) == std::string::npos) std::abort();
    }
  };
  check(&load_pcd);
  check(&load_ply);
  check(&load_cloud);
  std::remove(path.c_str());
  return accepted;
}

}  // namespace rgbdt::cloud::fuzz
