// Assembly speed: one tilt of 24 scans x 1081 beams must assemble in < 1 ms (issue 8).
#include <benchmark/benchmark.h>

#include <filesystem>

#include "../tests/stream_fixture.hpp"
#include "rgbdt/tilt_lidar/rawlog_io.hpp"

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
// The same per tilt in steady state, as the recorder and the mapper use it: one Assembler
// fed 10 s of stream (about 16 tilts), each tilt consumed (here: released) as it comes, so
// the allocator hands the next tilt warm memory instead of fresh pages.
void BM_AssembleSteadyState(benchmark::State& state) {
  const auto rig = test::test_rig();
  const test::MotionProfile m;
  const auto stream = test::make_stream(rig, m, 10.0);
  std::int64_t tilts = 0;
  for (auto _ : state) {
    tilt_lidar::Assembler a(rig);
    std::size_t points = 0;
    test::feed_each(a, stream, [&points](std::vector<tilt_lidar::TiltCloud>&& v) {
      for (const auto& c : v) points += c.cloud->size();  // released here, as a consumer would
    });
    benchmark::DoNotOptimize(points);
    tilts = a.stats().tilts;
  }
  const double scans = static_cast<double>(stream.scans.size());
  state.counters["scans"] = scans;
  state.counters["tilts"] = static_cast<double>(tilts);
  state.counters["ms_per_24_scan_tilt"] = benchmark::Counter(
      scans / 24.0 / 1e3 * static_cast<double>(state.iterations()), benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_AssembleSteadyState)->Unit(benchmark::kMillisecond);

// Recording throughput: everything the recorder does per observation except waiting for
// the devices (MRPT serialisation, one write(2) per record, live assembly), for 10 minutes
// of stream (24000 scans at 40/s + 120000 encoder samples at 200/s). Must run well faster
// than real time: the counter is the real-time factor (stream seconds per wall second).
void BM_RecordTenMinutes(benchmark::State& state) {
  const auto rig = test::test_rig();
  const test::MotionProfile m;
  const auto one = test::make_stream(rig, m, 6.0);  // 6 s pattern, shifted 100 times
  const std::string path = (std::filesystem::temp_directory_path() / "rgbdt_bench_record.rawlog").string();
  for (auto _ : state) {
    tilt_lidar::RawlogWriter writer(path, rig);
    tilt_lidar::Assembler assembler(rig);
    std::int64_t tilts = 0;
    for (int rep = 0; rep < 100; ++rep) {
      const double shift = 6.0 * rep;
      std::size_t e = 0;
      for (auto scan : one.scans) {
        scan.time_s += shift;
        for (; e < one.encoder.size() && one.encoder[e].time_s <= scan.time_s - shift + 0.025; ++e) {
          tilt_lidar::EncoderSample s = one.encoder[e];
          s.time_s += shift;
          writer.write(s, one.counts[e]);
          tilts += static_cast<std::int64_t>(assembler.add_encoder_sample(s).size());
        }
        writer.write(scan);
        tilts += static_cast<std::int64_t>(assembler.add_scan(scan).size());
      }
    }
    writer.close();
    benchmark::DoNotOptimize(tilts);
  }
  std::filesystem::remove(path);
  state.counters["realtime_factor"] =
      benchmark::Counter(600.0 * static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_RecordTenMinutes)->Unit(benchmark::kSecond)->Iterations(1);

}  // namespace

BENCHMARK_MAIN();
