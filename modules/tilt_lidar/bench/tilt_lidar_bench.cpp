// Assembly speed: one tilt of 24 scans x 1081 beams must assemble in < 1 ms (issue 8).
#include <benchmark/benchmark.h>

#include "../tests/stream_fixture.hpp"

namespace {

using namespace rgbdt;

void BM_AssembleOneTilt(benchmark::State& state) {
  const auto rig = test::test_rig();
  const test::MotionProfile m;
  // 0.3 .. 0.9 s is one full tilt; feed a little around it so both reversals are found.
  const auto stream = test::make_stream(rig, m, 1.0);
  std::int64_t points = 0;
  for (auto _ : state) {
    tilt_lidar::Assembler a(rig);
    const auto tilts = test::feed(a, stream);
    benchmark::DoNotOptimize(tilts.data());
    points = a.stats().points;
  }
  // The stream holds 39 scans; report time per 24-scan tilt.
  const double scans = static_cast<double>(stream.scans.size());
  state.counters["scans"] = scans;
  state.counters["points"] = static_cast<double>(points);
  state.counters["ms_per_24_scan_tilt"] = benchmark::Counter(
      scans / 24.0 / 1e3 * static_cast<double>(state.iterations()), benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_AssembleOneTilt)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
