// CSV stream I/O speed: reading and writing a 1,000,000-row heading gyro file (t,wz).
//
//   build/<preset>/benchmarks/bench_io
//
// The file is generated once into a temporary directory (removed at exit). Target: a read of
// the million rows well under 1 s.
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include <benchmark/benchmark.h>
#include <unistd.h>

#include "traverse/io/csv.h"
#include "traverse/io/log_writer.h"

namespace {

namespace fs = std::filesystem;
using traverse::io::Stream;

constexpr Eigen::Index kRows = 1'000'000;

/// 100 Hz heading gyro over ~2.8 h of mission time, noisy rates.
Stream makeGyro() {
  std::mt19937_64 rng(1);
  std::normal_distribution<double> noise(0.0, 0.0031);
  Stream s;
  s.columns = {"wz"};
  s.t.resize(kRows);
  s.values.resize(kRows, 1);
  for (Eigen::Index i = 0; i < kRows; ++i) {
    s.t[i] = 1.0e6 + 0.01 * static_cast<double>(i);
    s.values(i, 0) = 0.02 + noise(rng);
  }
  return s;
}

/// The temporary directory and its gyro.csv, made on first use, removed at exit.
struct Fixture {
  Fixture()
      : dir(fs::temp_directory_path() / ("traverse_bench_io_" + std::to_string(::getpid()))),
        gyro(makeGyro()) {
    fs::create_directories(dir);
    traverse::io::writeStream(dir / "gyro.csv", gyro);
    bytes = static_cast<std::int64_t>(fs::file_size(dir / "gyro.csv"));
  }
  ~Fixture() {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
  fs::path dir;
  Stream gyro;
  std::int64_t bytes = 0;
};

Fixture& fixture() {
  static Fixture f;
  return f;
}

void BM_ReadGyroCsv(benchmark::State& state) {
  const Fixture& f = fixture();
  const auto& spec = traverse::io::logStreamSpec("gyro.csv");
  for (auto _ : state) {
    Stream s = traverse::io::readCsv(f.dir / "gyro.csv", spec);
    benchmark::DoNotOptimize(s.values.data());
  }
  state.SetItemsProcessed(state.iterations() * kRows);
  state.SetBytesProcessed(state.iterations() * f.bytes);
}
BENCHMARK(BM_ReadGyroCsv)->Unit(benchmark::kMillisecond);

/// Parsing alone, the file already in memory.
void BM_ParseGyroCsv(benchmark::State& state) {
  const Fixture& f = fixture();
  std::ifstream in(f.dir / "gyro.csv", std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  const std::string csv = text.str();
  const auto& spec = traverse::io::logStreamSpec("gyro.csv");
  for (auto _ : state) {
    Stream s = traverse::io::parseCsv(csv, "gyro.csv", spec);
    benchmark::DoNotOptimize(s.values.data());
  }
  state.SetItemsProcessed(state.iterations() * kRows);
  state.SetBytesProcessed(state.iterations() * f.bytes);
}
BENCHMARK(BM_ParseGyroCsv)->Unit(benchmark::kMillisecond);

void BM_WriteGyroCsv(benchmark::State& state) {
  const Fixture& f = fixture();
  const fs::path out = f.dir / "gyro_out.csv";
  for (auto _ : state) traverse::io::writeStream(out, f.gyro);
  state.SetItemsProcessed(state.iterations() * kRows);
  state.SetBytesProcessed(state.iterations() * f.bytes);
}
BENCHMARK(BM_WriteGyroCsv)->Unit(benchmark::kMillisecond);

}  // namespace
