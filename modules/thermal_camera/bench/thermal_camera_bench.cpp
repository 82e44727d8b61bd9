// Throughput of the parts that run per frame or per start-up:
//   BM_RecorderWrite/<level>: 640x512 16-bit Tau2 frames written as PNG at a compression
//     level (items/s = frames/s the recorder sustains on one core; the rig needs 25-30).
//   BM_LookupTable/<type>: building the 65536-entry counts->kelvin table.
//   BM_Tau2Parse: parsing one SERIAL_NUMBER reply.
#include <benchmark/benchmark.h>

#include <filesystem>
#include <opencv2/core.hpp>

#include "rgbdt/thermal_camera/frame_recorder.hpp"
#include "rgbdt/thermal_camera/radiometry.hpp"
#include "rgbdt/thermal_camera/tau2_protocol.hpp"

using namespace rgbdt::thermal_camera;
namespace fs = std::filesystem;

static void BM_RecorderWrite(benchmark::State& state) {
  const fs::path dir = fs::temp_directory_path() / "rgbdt_bench_recorder";
  Frame frame;
  // A thermal-like scene: smooth gradient plus sensor noise (14-bit counts around 7500).
  frame.image.create(512, 640, CV_16UC1);
  cv::Mat noise(512, 640, CV_16SC1);
  cv::randn(noise, 0, 8);
  for (int v = 0; v < 512; ++v) {
    for (int u = 0; u < 640; ++u) {
      frame.image.at<uint16_t>(v, u) =
          static_cast<uint16_t>(7000 + u + v / 2 + noise.at<int16_t>(v, u));
    }
  }
  frame.pixel_format = "Mono16";
  int run = 0;
  for (auto _ : state) {
    state.PauseTiming();
    fs::remove_all(dir);
    FrameRecorderOptions o;
    o.out_dir = (dir / std::to_string(run++)).string();
    o.png_compression = static_cast<int>(state.range(0));
    FrameRecorder recorder(o);
    state.ResumeTiming();
    for (int i = 0; i < 10; ++i) recorder.write(frame, i * 0.04);
  }
  state.SetItemsProcessed(state.iterations() * 10);
  fs::remove_all(dir);
}
BENCHMARK(BM_RecorderWrite)->Arg(0)->Arg(1)->Arg(3)->Arg(6)->Unit(benchmark::kMillisecond);

static void BM_LookupTable(benchmark::State& state) {
  PlanckRadiometry p;
  p.R = 366545;
  p.B = 1428;
  p.F = 1;
  p.O = -342;
  p.emissivity = 0.95;
  const Radiometry r =
      state.range(0) == 0 ? Radiometry(LinearRadiometry{0.04, 0.0}) : Radiometry(p);
  for (auto _ : state) benchmark::DoNotOptimize(r.lookup_table());
  state.SetLabel(state.range(0) == 0 ? "linear" : "planck");
}
BENCHMARK(BM_LookupTable)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

static void BM_Tau2Parse(benchmark::State& state) {
  const auto bytes = tau2::encode({0, 0x04, tau2::words({1, 57920, 9, 64497})});
  for (auto _ : state) benchmark::DoNotOptimize(tau2::parse(bytes.data(), bytes.size()));
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_Tau2Parse);

BENCHMARK_MAIN();
