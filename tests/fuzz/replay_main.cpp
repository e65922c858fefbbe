// Runs a libFuzzer target without libFuzzer (GCC builds, CI): every seed file given on the command
// line, then deterministic mutations of each (byte flips, truncations, splices), so the target's
// checks run under the sanitizers on every test run. Usage: TARGET [--mutations N] SEED...
// With MTLOD_REPLAY_SAVE=FILE, each input is written to FILE before it runs: after a crash, FILE
// holds the input that caused it.
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size);

int main(int argc, char** argv) {
  int mutations = 2000;
  std::vector<std::vector<std::uint8_t>> seeds;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--mutations") == 0 && i + 1 < argc) {
      mutations = std::atoi(argv[++i]);
      continue;
    }
    std::ifstream in(argv[i], std::ios::binary);
    if (!in) {
      std::fprintf(stderr, "cannot read seed %s\n", argv[i]);
      return 2;
    }
    seeds.emplace_back(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  if (seeds.empty()) seeds.emplace_back();
  const char* save = std::getenv("MTLOD_REPLAY_SAVE");
  auto run = [save](const std::vector<std::uint8_t>& input) {
    if (save) {
      std::ofstream out(save, std::ios::binary);
      out.write(reinterpret_cast<const char*>(input.data()), static_cast<std::streamsize>(input.size()));
    }
    LLVMFuzzerTestOneInput(input.data(), input.size());
  };
  std::mt19937 rng(12345);
  std::size_t runs = 0;
  for (const auto& seed : seeds) {
    run(seed);
    ++runs;
    for (int m = 0; m < mutations; ++m) {
      std::vector<std::uint8_t> input = seed;
      switch (rng() % 4) {
        case 0:  // flip a few bytes
          for (int k = 0, n = 1 + static_cast<int>(rng() % 4); k < n && !input.empty(); ++k) {
            input[rng() % input.size()] = static_cast<std::uint8_t>(rng());
          }
          break;
        case 1:  // truncate
          input.resize(input.empty() ? 0 : rng() % input.size());
          break;
        case 2:  // duplicate a slice somewhere else
          if (input.size() > 2) {
            const std::size_t a = rng() % input.size(), len = 1 + rng() % (input.size() - a);
            const std::vector<std::uint8_t> slice(input.begin() + a, input.begin() + a + len);
            input.insert(input.begin() + rng() % input.size(), slice.begin(), slice.end());
          }
          break;
        default:  // set a byte to an edge value
          if (!input.empty()) input[rng() % input.size()] = (rng() % 2) ? 0xFF : 0x00;
      }
      run(input);
      ++runs;
    }
  }
  std::printf("%zu inputs run\n", runs);
  return 0;
}
